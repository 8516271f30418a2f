"""The ``jaxmotion`` command line.

Subcommands import their heavy modules lazily, so ``jaxmotion --help`` and
``jaxmotion version`` start in well under a second and compile nothing.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from jaxmotion._version import __version__


def _cmd_version(args: argparse.Namespace) -> int:
    print(f"jaxmotion {__version__}")
    if args.verbose:
        from importlib import metadata

        for pkg in ("jax", "jaxlib", "flax", "optax", "orbax-checkpoint", "numpy", "trimesh"):
            try:
                print(f"  {pkg} {metadata.version(pkg)}")
            except metadata.PackageNotFoundError:
                print(f"  {pkg} (not installed)")
        import jax

        print(f"  devices: {', '.join(str(d) for d in jax.devices())}")
    return 0


def _cmd_scene_info(args: argparse.Namespace) -> int:
    from jaxmotion.scene import load_scene

    scene = load_scene(args.path, num_points=args.points, seed=args.seed, up=args.up)
    lo, hi = scene.bounds()
    info = {
        "name": scene.name,
        "points": scene.num_points,
        "bounds_min": [round(float(v), 4) for v in lo],
        "bounds_max": [round(float(v), 4) for v in hi],
        "has_normals": bool((abs(scene.normal).sum(axis=1) > 0).any()),
        "labelled_points": int((scene.semantic >= 0).sum()),
        "instances": int(len(set(scene.instance[scene.instance >= 0].tolist()))),
        "objects": len(scene.objects),
    }
    print(json.dumps(info, indent=2))
    return 0


def _cmd_scene_convert(args: argparse.Namespace) -> int:
    from jaxmotion.scene import load_scene, save_scene

    scene = load_scene(args.src, num_points=args.points, seed=args.seed, up=args.up)
    out = save_scene(scene, args.dst)
    print(f"wrote {out} ({scene.num_points} points)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxmotion",
        description="Language-guided human motion generation in 3D scenes (JAX/Flax).",
        epilog="Run 'jaxmotion COMMAND --help' for the options of a command.",
    )
    parser.add_argument("--version", action="version", version=f"jaxmotion {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("version", help="print the version (and dependencies with -v)")
    p.add_argument("-v", "--verbose", action="store_true", help="also list dependencies and devices")
    p.set_defaults(func=_cmd_version)

    scene = sub.add_parser("scene", help="inspect or convert a room scan, mesh or point cloud")
    scene_sub = scene.add_subparsers(dest="scene_command", metavar="ACTION", required=True)

    def scene_common(q):
        q.add_argument("--points", type=int, default=None, help="points to sample from a mesh")
        q.add_argument("--seed", type=int, default=0, help="sampling seed")
        q.add_argument("--up", choices=("auto", "z", "y"), default="auto", help="up axis of the file")

    q = scene_sub.add_parser("info", help="load a scene and print a summary as JSON")
    q.add_argument("path", help="PLY / OBJ / GLB / GLTF / OFF / STL / NPZ file")
    scene_common(q)
    q.set_defaults(func=_cmd_scene_info)

    q = scene_sub.add_parser("convert", help="load a scene and save it as jaxmotion .npz")
    q.add_argument("src", help="input mesh or point cloud")
    q.add_argument("dst", help="output .npz")
    scene_common(q)
    q.set_defaults(func=_cmd_scene_convert)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError, KeyError) as err:
        # Expected user errors (bad file, bad config): one clear line, no traceback.
        msg = err.args[0] if isinstance(err, KeyError) and err.args else err
        print(f"jaxmotion {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
