"""Config files, command-line overrides and ``config.json`` (pure Python, no JAX).

A config is a frozen dataclass (nested dataclasses allowed) returned by ``get_config()`` in a
file under ``configs/``. Command lines change it with ``key=value`` strings, nested keys dotted
(``crop.num_points=256``), values parsed by the field's annotated type (bool, int, float, str,
``X | None``, ``tuple[X, ...]``, ``Literal[...]``); mistakes raise :class:`ConfigError`.

Presets: ``get_config()`` takes no arguments; a config file may define a module-level
``PRESETS: dict[str, dict[str, Any]]`` mapping a preset name to overrides (dotted keys to Python
values, or strings parsed as on the command line). ``default`` always exists. ``load_config``
applies ``preset=NAME`` first wherever it appears, then the other overrides in order, all in one
:func:`dataclasses.replace` per config, so ``__post_init__`` checks see only the final values.
``preset`` is therefore a reserved key.

Config files run under a private module name kept out of ``sys.modules`` and are re-run only when
they change; a file already imported (e.g. as ``configs.data``) is reused, so ``isinstance`` holds.
Privately loaded classes cannot be pickled: serialise with :func:`config_to_dict`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import importlib.util
import json
import os
import re
import sys
import types
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal, Union

__all__ = [
    "ConfigError", "load_config", "apply_overrides", "config_to_dict", "config_from_dict",
    "save_config_json", "load_config_json", "format_config", "flatten_config",
]

_PACKAGE_ROOT = Path(__file__).resolve().parent.parent  # the repo holding jaxmotion/ and configs/
_NONE_WORDS = frozenset({"none", "null"})
_BOOL_WORDS = {"true": True, "1": True, "yes": True, "false": False, "0": False, "no": False}
_INT_RE = re.compile(r"[+-]?\d+")
_UNIONS = (Union, types.UnionType)
_HINTS = {tuple: " (write tuples as 1,2,3 or (1,2,3) or [1,2,3])", bool: " (true/false/yes/no/1/0)"}
_MODULE_GLOBALS: dict[str, dict[str, Any]] = {}  # privately loaded config files, for type hints
_LOADED: dict[Path, tuple[int, types.ModuleType]] = {}  # file -> (mtime, module)


class ConfigError(ValueError):
    """A config file, override or serialised config is wrong; the message says how to fix it."""


class _Mismatch(Exception):
    """Internal: a value does not fit a type (turned into a ConfigError by the caller)."""


class _Sub(dict):
    """Internal marker: pending changes of a nested config, as opposed to a dict-valued leaf."""


def _is_cfg(x: Any) -> bool:
    return dataclasses.is_dataclass(x) and not isinstance(x, type)


def _is_cfg_type(tp: Any) -> bool:
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


def _hints(cls: type) -> dict[str, Any]:
    """Resolved field annotations of a dataclass, also for privately loaded config files.

    Each class in the MRO resolves its own annotations in its own module's namespace, so a
    config class in a privately loaded file can derive from a class of another module.
    """
    hints: dict[str, Any] = {}
    for base in reversed(cls.__mro__):
        own = base.__dict__.get("__annotations__")
        if base is object or not own:
            continue
        mod = sys.modules.get(base.__module__)
        globalns = dict(vars(mod)) if mod is not None else dict(
            _MODULE_GLOBALS.get(base.__module__, {}))
        # A bare stand-in class carrying only this base's own annotations.
        stand_in = type("_Annotations", (), {"__annotations__": dict(own)})
        hints.update(typing.get_type_hints(stand_in, globalns=globalns, localns=dict(vars(base))))
    return hints


def _fields(obj: Any) -> dict[str, dataclasses.Field]:
    """The ``init=True`` fields of a dataclass (instance or class) by name, in order."""
    return {f.name: f for f in dataclasses.fields(obj) if f.init}


def _type_name(tp: Any) -> str:
    """Readable annotation: ``int | None``, ``tuple[float, ...]``, ``one of 'a', 'b'``."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp is type(None):
        return "None"
    if origin in _UNIONS:
        return " | ".join(_type_name(a) for a in args)
    if origin is Literal:
        return "one of " + ", ".join(repr(c) for c in args)
    if origin is tuple:
        return f"tuple[{', '.join('...' if a is Ellipsis else _type_name(a) for a in args)}]"
    return getattr(tp, "__name__", repr(tp))


def _convert(value: Any, tp: Any, key: str, cli: bool) -> Any:
    """Convert ``value`` to annotated type ``tp`` or raise _Mismatch.

    With ``cli`` the value is a command-line string to parse (stripped; one pair of matching
    outer quotes protects a str such as ``'none'``); otherwise a Python value to validate,
    coercing int to float, list to tuple and a mapping (read from JSON) to a nested dataclass.
    """
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    raw, quoted = value, False
    if cli:
        value = value.strip()
        quoted = len(value) >= 2 and value[0] == value[-1] and value[0] in "'\""
        value = value[1:-1] if quoted else value
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if tp is Any or isinstance(tp, type) and isinstance(value, tp) and not (
            tp is int and isinstance(value, bool)):  # includes str, and e.g. lists for list
        return value
    if _is_cfg_type(tp) and not cli and isinstance(value, Mapping):
        return config_from_dict(tp, value, key + ".")
    if origin in _UNIONS:
        if type(None) in args and (value is None or cli and not quoted and value.lower() in
                                   _NONE_WORDS):
            return None
        for arm in args:
            with contextlib.suppress(_Mismatch):
                return _convert(raw, arm, key, cli)
    elif origin is Literal:
        for choice in args:
            with contextlib.suppress(_Mismatch):
                v = _convert(raw, type(choice), key, cli)
                if type(v) is type(choice) and v == choice:
                    return choice
    elif tp is bool and cli and value.lower() in _BOOL_WORDS:
        return _BOOL_WORDS[value.lower()]
    elif tp is int and cli and _INT_RE.fullmatch(value):
        return int(value)
    elif tp is float and (number or cli):
        with contextlib.suppress(ValueError):
            return float(value)
    elif origin is tuple and (cli or isinstance(value, (list, tuple))):
        if cli:  # "1,2,3", "(1,2,3)", "[1,2,3]", "1," and "()" / "" (empty)
            value = value[1:-1] if value[:1] + value[-1:] in ("()", "[]") else value
            value = [p.strip() for p in value.split(",")]
            value = value[:-1] if value[-1] == "" else value
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(v, args[0], key, cli) for v in value)
        if len(value) == len(args):
            return tuple(_convert(v, a, key, cli) for v, a in zip(value, args))
    raise _Mismatch  # also types the command line cannot express (list, dict, ...)


def _unknown_key(root: Any, obj: Any, key: str, prefix: str, part: str) -> ConfigError:
    """Error for ``key`` whose component ``part`` is not a field of ``obj`` (at ``prefix``)."""
    names = list(_fields(obj))
    same_leaf = [k for k in flatten_config(root) if k.rsplit(".", 1)[-1] == part]
    close = [prefix + n for n in difflib.get_close_matches(part, names, n=1)]
    where = (f"under '{prefix[:-1]}' " if prefix else "in ") + type(obj).__name__
    msg = f"unknown config key '{key}': no field '{part}' {where}."
    if same_leaf or close:
        msg += f" Did you mean '{(same_leaf or close)[0]}'?"
    valid = [n + ".*" if _is_cfg(getattr(obj, n)) else n for n in names]
    return ConfigError(f"{msg} Valid keys {where}: {', '.join(valid)}")


def _split(override: str, cfg: Any) -> tuple[str, str]:
    """Split ``key=value``; raise a ConfigError showing the expected form otherwise."""
    key, sep, value = str(override).partition("=")
    key = key.strip()
    if not sep or not key or any(not p for p in key.split(".")):
        example = next(iter(flatten_config(cfg)), "key")
        raise ConfigError(f"malformed override {override!r}: expected key=value with a "
                          f"(dotted) key, e.g. '{example}=...'")
    return key, value


def _apply(cfg: Any, items: Sequence[tuple[str, Any, bool, str]]) -> Any:
    """Apply ``(key, value, value_is_cli_string, source)`` items; one replace per config."""
    changes = _Sub()
    for key, value, is_str, source in items:
        where = f" ({source})" if source else ""
        obj, node, parts = cfg, changes, key.split(".")
        for i, part in enumerate(parts):
            prefix = "".join(p + "." for p in parts[:i])
            if part not in _fields(obj):
                raise ConfigError(f"{_unknown_key(cfg, obj, key, prefix, part)}{where}")
            tp, current = _hints(type(obj))[part], getattr(obj, part)
            if i < len(parts) - 1:
                if not _is_cfg(current):
                    raise ConfigError(f"cannot set '{key}'{where}: '{prefix}{part}' has type "
                                      f"{_type_name(tp)} and is not a nested config")
                obj, node = current, node.setdefault(part, _Sub())
        if _is_cfg(current) or _is_cfg_type(tp):
            fields = ", ".join(f"{key}.{n}=..." for n in _fields(current))
            raise ConfigError(f"'{key}' is a nested config ({type(current).__name__}) and cannot "
                              f"be set directly{where}; set its fields instead: {fields}")
        # a Python value (preset, mapping) that is a str and does not fit is parsed as well
        for cli in [is_str] + [True] * (not is_str and isinstance(value, str)):
            with contextlib.suppress(_Mismatch):
                node[part] = _convert(value, tp, key, cli=cli)
                break
        else:
            hint = _HINTS.get(typing.get_origin(tp) or tp, "")
            raise ConfigError(f"bad value for '{key}'{where}: expected {_type_name(tp)}, "
                              f"got {value!r}{hint}") from None
    return _rebuild(cfg, changes, "")


def _rebuild(obj: Any, node: _Sub, prefix: str) -> Any:
    kwargs = {name: _rebuild(getattr(obj, name), v, f"{prefix}{name}.") if isinstance(v, _Sub)
              else v for name, v in node.items()}
    try:
        return dataclasses.replace(obj, **kwargs) if kwargs else obj
    except (TypeError, ValueError) as e:
        raise ConfigError(f"invalid {type(obj).__name__} after setting "
                          f"{', '.join(prefix + k for k in kwargs)}: {e}") from e


def apply_overrides(cfg: Any, overrides: Sequence[str] | Mapping[str, Any]) -> Any:
    """Return a copy of the frozen config ``cfg`` with overrides applied (``cfg`` is untouched).

    ``overrides`` is a sequence of ``"key=value"`` strings (values parsed by field type) or a
    mapping from dotted keys to Python values (strings that do not fit are parsed likewise).
    Later overrides of the same key win. Raises ConfigError on any mistake.
    """
    if not _is_cfg(cfg):
        raise ConfigError(f"expected a dataclass config instance, got {type(cfg).__name__}")
    overrides = [overrides] if isinstance(overrides, str) else overrides  # a lone "key=value"
    if isinstance(overrides, Mapping):
        items = [(_split(f"{k}=", cfg)[0], v, False, "") for k, v in overrides.items()]
    else:
        items = [(*_split(o, cfg), True, "") for o in overrides]
    return _apply(cfg, items)


def _find_config_file(path_or_name: str) -> Path:
    if path_or_name.endswith(".py") or "/" in path_or_name or os.sep in path_or_name:
        candidates = [Path(path_or_name)]
    else:
        candidates = [d / "configs" / f"{path_or_name}.py" for d in (Path.cwd(), _PACKAGE_ROOT)]
    for c in candidates:
        if c.is_file():
            return c.resolve()
    names = sorted({p.stem for c in candidates if c.parent.is_dir()
                    for p in c.parent.glob("*.py") if not p.stem.startswith("_")})
    raise ConfigError(f"config {path_or_name!r} not found (looked at "
                      f"{', '.join(map(str, candidates))}); available configs: "
                      f"{', '.join(names) or 'none'}; pass a name like 'data' or a file path")


def _load_module(path: Path) -> types.ModuleType:
    for module in list(sys.modules.values()):  # reuse an import of the same file
        file = getattr(module, "__file__", None)
        if file and os.path.basename(file) == path.name and Path(file).resolve() == path:
            return module
    mtime = path.stat().st_mtime_ns
    if path in _LOADED and _LOADED[path][0] == mtime:  # same class for repeated loads
        return _LOADED[path][1]
    name = f"_jaxmotion_config_{path.stem}_{len(_MODULE_GLOBALS)}"  # unique: it only grows
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # only while executing: dataclasses looks up ClassVar there
    try:
        spec.loader.exec_module(module)
    except Exception as e:
        raise ConfigError(f"error while executing config file {path}: {e!r}") from e
    finally:
        sys.modules.pop(name, None)
    _MODULE_GLOBALS[name], _LOADED[path] = vars(module), (mtime, module)
    return module


def _check_frozen(cfg: Any, key: str = "") -> None:
    if not type(cfg).__dataclass_params__.frozen:
        raise ConfigError(f"config {key[:-1] or 'root'} ({type(cfg).__name__}) must be a frozen "
                          "dataclass: use @dataclasses.dataclass(frozen=True)")
    for name in _fields(cfg):
        if _is_cfg(value := getattr(cfg, name)):
            _check_frozen(value, f"{key}{name}.")


def load_config(path_or_name: str, overrides: Sequence[str] = ()) -> Any:
    """Load ``configs/NAME.py`` (or a file path), apply ``preset=NAME`` then ``overrides``.

    A bare name is looked up in ``./configs`` and then in the ``configs`` folder next to the
    ``jaxmotion`` package. Returns the frozen config; raises ConfigError on any mistake.
    """
    path = _find_config_file(str(path_or_name))
    module = _load_module(path)
    if not callable(get_config := getattr(module, "get_config", None)):
        raise ConfigError(f"config file {path} must define get_config() returning a dataclass")
    if not _is_cfg(cfg := get_config()):
        raise ConfigError(f"get_config() in {path} returned {type(cfg).__name__}, "
                          "not a dataclass instance")
    _check_frozen(cfg)
    presets = {"default": {}, **(getattr(module, "PRESETS", None) or {})}
    overrides = [overrides] if isinstance(overrides, str) else overrides
    pairs = [_split(o, cfg) for o in overrides]
    chosen = sorted({v.strip() for k, v in pairs if k == "preset"})
    if len(chosen) > 1:
        raise ConfigError(f"preset given more than once with different values {chosen}; "
                          "pass a single preset=NAME")
    preset = chosen[0] if chosen else "default"
    if preset not in presets:
        guess = difflib.get_close_matches(preset, list(presets), n=1)
        raise ConfigError(f"unknown preset {preset!r} for {path.name}."
                          + (f" Did you mean {guess[0]!r}?" if guess else "")
                          + f" Valid presets: {', '.join(sorted(presets))}")
    items = [(k, v, False, f"preset {preset!r}") for k, v in presets[preset].items()]
    return _apply(cfg, items + [(k, v, True, "") for k, v in pairs if k != "preset"])


def config_to_dict(cfg: Any) -> dict[str, Any]:
    """Nested JSON-ready dict of a config (tuples become lists); inverse of config_from_dict."""
    def to_json(value: Any, key: str) -> Any:
        if _is_cfg(value):
            return {n: to_json(getattr(value, n), f"{key}.{n}".lstrip(".")) for n in _fields(value)}
        if isinstance(value, (tuple, list)):
            return [to_json(v, key) for v in value]
        if value is None or isinstance(value, (bool, int, float, str)):
            return value
        raise ConfigError(f"value of '{key}' has type {type(value).__name__}, which config.json "
                          "cannot store; use bool, int, float, str, None or tuples of them")
    return to_json(cfg, "")


def config_from_dict(cls: type, d: Mapping[str, Any], _prefix: str = "") -> Any:
    """Build config class ``cls`` from a dict made by config_to_dict (unknown keys are errors).

    Keys missing from ``d`` keep the field's default so that older ``config.json`` files load.
    """
    if not _is_cfg_type(cls) or not isinstance(d, Mapping):
        raise ConfigError(f"config_from_dict needs a dataclass type and a dict for "
                          f"{_prefix[:-1] or 'it'}, got {cls!r} and {d!r}")
    fields, hints, prefix = _fields(cls), _hints(cls), _prefix
    for key in d:
        if key not in fields:
            guess = difflib.get_close_matches(str(key), list(fields), n=1)
            raise ConfigError(f"unknown key '{prefix}{key}' for {cls.__name__}."
                              + (f" Did you mean '{prefix}{guess[0]}'?" if guess else "")
                              + f" Valid keys: {', '.join(fields)}")
    kwargs = {}
    for name, f in fields.items():
        if name not in d:  # e.g. a field added after the file was written: keep its default
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise ConfigError(f"missing key '{prefix}{name}' for {cls.__name__}")
            continue
        try:
            kwargs[name] = _convert(d[name], hints[name], prefix + name, cli=False)
        except _Mismatch:
            raise ConfigError(f"bad value for '{prefix}{name}': expected "
                              f"{_type_name(hints[name])}, got {d[name]!r}") from None
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as e:
        raise ConfigError(f"invalid {cls.__name__} {prefix[:-1]}".rstrip() + f": {e}") from e


def save_config_json(cfg: Any, path: str | os.PathLike) -> Path:
    """Write ``config_to_dict(cfg)`` as JSON to ``path`` atomically (temp file + os.replace)."""
    path = Path(path)
    text = json.dumps(config_to_dict(cfg), indent=2) + "\n"
    from jaxmotion._atomic import atomic_open

    with atomic_open(path, "w") as f:
        f.write(text)
    return path


def load_config_json(cls: type, path: str | os.PathLike) -> Any:
    """Read a ``config.json`` written by save_config_json back into config class ``cls``."""
    with open(path, encoding="utf-8") as f:
        return config_from_dict(cls, json.load(f))


def flatten_config(cfg: Any, _prefix: str = "") -> dict[str, Any]:
    """``{dotted key: value}`` of every leaf field, e.g. for logging hyper-parameters."""
    flat: dict[str, Any] = {}
    for name in _fields(cfg):
        value = getattr(cfg, name)
        flat.update(flatten_config(value, f"{_prefix}{name}.") if _is_cfg(value)
                    else {_prefix + name: value})
    return flat


def format_config(cfg: Any, _indent: int = 1) -> str:
    """Readable multi-line dump: the class name, then ``name: value`` lines, nested indented."""
    lines = [type(cfg).__name__] if _indent == 1 else []
    for name in _fields(cfg):
        value = getattr(cfg, name)
        if _is_cfg(value):
            lines.append(f"{'  ' * _indent}{name}: {type(value).__name__}")
            lines += format_config(value, _indent + 1).splitlines()
        else:
            lines.append(f"{'  ' * _indent}{name}: {value!r}")
    return "\n".join(lines)
