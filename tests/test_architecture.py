"""The package's structure rules, checked on the source (AST), not by convention:

- no import cycles between jaxmotion's modules (lazy imports inside functions count too);
- nothing outside ``jaxmotion/train/`` imports ``jaxmotion.train`` (inference below training);
- no module, and no test, uses another module's private names (``from m import _x``, ``m._x``);
- ``generation.py`` only orchestrates (under 300 lines).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "jaxmotion"


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PKG.rglob("*.py"))}


def _resolve(name: str, known: dict[str, Path]) -> str | None:
    """The longest known module that ``name`` (a dotted import target) names."""
    while name and name not in known:
        name = name.rpartition(".")[0]
    return name or None


def _imports(path: Path, known: dict[str, Path]):
    """``(target module, imported names or None, line)`` for every import in ``path``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    me = _module_name(path)
    is_pkg = path.name == "__init__.py"
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("jaxmotion"):
                    yield _resolve(a.name, known), None, node.lineno
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = me if is_pkg else me.rpartition(".")[0]
                for _ in range(node.level - 1):
                    pkg = pkg.rpartition(".")[0]
                base = f"{pkg}.{base}" if base else pkg
            if not base.startswith("jaxmotion"):
                continue
            for a in node.names:
                sub = f"{base}.{a.name}"
                if sub in known:  # "from jaxmotion import export": the module itself
                    yield sub, None, node.lineno
                else:
                    yield _resolve(base, known), a.name, node.lineno


def _graph():
    known = _modules()
    return known, {m: {t for t, _, _ in _imports(p, known) if t and t != m}
                   for m, p in known.items()}


def _is_ancestor(pkg: str, mod: str) -> bool:
    return mod.startswith(pkg + ".")


def test_no_import_cycles():
    _, graph = _graph()
    # a package's __init__ re-exporting its submodules is not a cycle with them: drop the
    # edges from a package to its own submodules and from a module to its ancestor packages
    edges = {m: {t for t in ts if not _is_ancestor(m, t) and not _is_ancestor(t, m)}
             for m, ts in graph.items()}
    state: dict[str, int] = {}
    cycles = []

    def visit(m, stack):
        state[m] = 1
        stack.append(m)
        for t in sorted(edges.get(m, ())):
            if state.get(t) == 1:
                cycles.append(stack[stack.index(t):] + [t])
            elif t not in state:
                visit(t, stack)
        stack.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m, [])
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_only_training_imports_training():
    known, graph = _graph()
    bad = [f"{m} imports {t}" for m, ts in graph.items() for t in ts
           if (t == "jaxmotion.train" or t.startswith("jaxmotion.train."))
           and not (m == "jaxmotion.train" or m.startswith("jaxmotion.train."))]
    assert not bad, "inference code imports training:\n" + "\n".join(bad)


def _private_uses(path: Path, known: dict[str, Path]) -> list[str]:
    """``from m import _x`` and ``alias._x`` (alias: an imported jaxmotion module) in ``path``."""
    me = _module_name(path) if path.is_relative_to(PKG) else None
    out = []
    aliases = {}
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("jaxmotion") and a.asname:
                    aliases[a.asname] = a.name
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("jaxmotion"):
            for a in node.names:
                if f"{node.module}.{a.name}" in known:
                    aliases[a.asname or a.name] = f"{node.module}.{a.name}"
    for target, name, line in _imports(path, known):
        if name and name.startswith("_") and target != me and not name.startswith("__"):
            out.append(f"{path.relative_to(ROOT)}:{line}: from {target} import {name}")
    own_classes = {n.name for n in ast.walk(tree) if isinstance(n, ast.ClassDef)}
    # privates this module defines itself (``self._x = ...``, methods ``_x``): its own business
    own_privates = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)
                    and isinstance(n.value, ast.Name) and n.value.id == "self"
                    and isinstance(n.ctx, ast.Store)}
    own_privates |= {n.name for c in ast.walk(tree) if isinstance(c, ast.ClassDef)
                     for n in c.body if isinstance(n, (ast.FunctionDef, ast.Assign))
                     and getattr(n, "name", "").startswith("_")}
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and node.attr.startswith("_")
                and not node.attr.startswith("__")):
            continue
        base = node.value
        if isinstance(base, ast.Name) and base.id in aliases:
            out.append(f"{path.relative_to(ROOT)}:{node.lineno}: "
                       f"{aliases[base.id]}.{node.attr}")
        elif isinstance(base, ast.Name) and base.id in ("self", "cls", *own_classes):
            continue  # an object's own privates, in its own module
        elif node.attr in own_privates and path.is_relative_to(PKG):
            continue  # a private this module defines, used elsewhere in the same module
        elif isinstance(base, (ast.Name, ast.Call, ast.Attribute)) and not _third_party(base):
            out.append(f"{path.relative_to(ROOT)}:{node.lineno}: "
                       f"{ast.unparse(base)}.{node.attr} (another object's private attribute)")
    return out


def _third_party(node) -> bool:
    """Whether an attribute chain starts at a third-party module (numpy's ``np._x`` is theirs)."""
    while isinstance(node, (ast.Attribute, ast.Call)):
        node = node.value if isinstance(node, ast.Attribute) else node.func
    return isinstance(node, ast.Name) and node.id in {
        "np", "jnp", "jax", "os", "sys", "nnx", "warnings", "threading", "mp", "trimesh",
        "functools", "tempfile", "plt", "matplotlib", "multiprocessing", "jexport", "optax"}


def test_no_private_names_across_modules():
    known = _modules()
    files = sorted(PKG.rglob("*.py")) + sorted((ROOT / "tests").glob("*.py"))
    bad = [u for f in files for u in _private_uses(f, known)]
    assert not bad, "private names used from another module:\n" + "\n".join(bad)


def test_generation_only_orchestrates():
    lines = (PKG / "generation.py").read_text().count("\n")
    assert lines < 300, f"generation.py has {lines} lines; move stages into their modules"


def test_a_cached_generate_imports_no_network_library():
    """The modules a cached ``generate`` runs through import neither Flax, jaxopt nor SciPy's
    spatial module (together ~1 s of every command's start-up): networks and the body fit
    are imported inside the functions that build them."""
    import subprocess
    import sys

    mods = ("jaxmotion.cli", "jaxmotion.generation", "jaxmotion.pipelines.object_centric",
            "jaxmotion.pipelines.checkpoints", "jaxmotion.text.condition", "jaxmotion.grounding",
            "jaxmotion.grounding.region", "jaxmotion.export", "jaxmotion.export.folder",
            "jaxmotion.scene.demo", "jaxmotion.planning.control", "jaxmotion.compiled",
            "jaxmotion.diffusion.anchor_guidance", "jaxmotion.models.weights",
            "jaxmotion.eval.plausibility")
    code = ("import sys\n" + "".join(f"import {m}\n" for m in mods) +
            "print(sorted(m for m in ('flax', 'jaxopt', 'scipy.spatial', 'optax') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip().splitlines()[-1]
    assert out == "[]", f"imported at start-up: {out}"
