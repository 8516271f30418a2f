"""``python -m jaxmotion.train --config configs/<name>.py [key=value ...]``.

Loads the config (``preset=...`` first, then the overrides in order), prints it,
and trains (resuming from the last checkpoint in ``workdir`` unless
``resume=false``). See ``configs/*.py`` for the configs and their presets.
"""

from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m jaxmotion.train",
        description="Train a jaxmotion model from a config file with key=value overrides.",
        epilog="examples: --config configs/segmentation.py preset=tiny data_dir=DIR "
               "workdir=DIR steps=N",
    )
    ap.add_argument("--config", required=True, help="configs/<name>.py (or a bare name)")
    ap.add_argument("overrides", nargs="*", help="key=value (nested: a.b=value)")
    args = ap.parse_args(argv)

    from jaxmotion._jax_setup import enable_compilation_cache
    from jaxmotion.config import ConfigError, format_config, load_config

    try:
        cfg = load_config(args.config, args.overrides)
    except (ConfigError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    enable_compilation_cache()
    print(format_config(cfg), flush=True)
    from jaxmotion.train.loop import train
    from jaxmotion.train.tasks import get_task

    try:
        result = train(cfg, get_task(cfg))
    except (ValueError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    msg = f"done: step {result.step}, loss {result.last_loss:.4f}"
    if result.val_loss is not None:
        msg += f", val_loss {result.val_loss:.4f}"
    print(msg + f", workdir {result.workdir}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
