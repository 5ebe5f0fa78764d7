"""Scene files: a linkage, and the settings of its statics and dynamics, as TOML.

A scene file holds what :class:`~sorojax.Linkage` is built from: the links (soft:
divisions with sections, strain bases and materials; rigid: shape or mass and
inertia), their joints, parents and placements, gravity, point wrenches, actuators
(joint actuators and cables with their paths), closed-loop joints and contact, and
optionally the inputs and settings of a statics solve (``[statics]``) and of a
simulation (``[simulate]``). Every table is read by the schema below (:data:`SPECS`),
which also writes files and generates the key reference of the docs
(:func:`key_reference`), so that the three cannot drift apart.

Reading uses the standard library's ``tomllib`` (``tomli`` before Python 3.11);
writing uses ``tomlkit``. A file is checked as it is read: an unknown key, a missing
one, a value of the wrong type, a non-finite number, or any value the model's
constructors refuse ends with a :class:`SceneError` naming the file, the key (with
its line), the value and the fix. Python functions (custom paths, profiles and
bases, hooks, moving obstacles, time-dependent wrenches) are written as
``"module:function"`` (an ``equinox.Partial`` of one as a table with its arguments);
other callables (lambdas, closures) cannot be saved and are refused by name.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import os
import re
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from ._files import as_path, writing

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

FORMAT = "sorojax-scene"
"""The value of a scene file's ``format`` key."""
VERSION = 1
"""The format version this sorojax reads and writes."""

REQUIRED = "(required)"
_ABSENT = object()


class SceneError(ValueError):
    """A scene file that cannot be read: names the file, the key, its line, the value.

    Attributes:
        file: the file's path (``"<string>"`` for text).
        key: the key's path in the file, e.g. ``links[1].divisions[0].length``.
        line: the line of the key (or of the table holding it), or None.
    """

    def __init__(self, file: str, key: str, message: str, line: int | None = None):
        self.file, self.key, self.line = file, key, line
        where = f"{file}, line {line}" if line else file
        super().__init__(f"{where}: {key}: {message}" if key else f"{where}: {message}")


class _Fail(Exception):
    """Raised inside the decoder: ``(path, message)``; the reader adds file and line."""

    def __init__(self, path: str, message: str):
        super().__init__(path, message)
        self.path, self.message = path, message


def _show(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


# ============================================================== value kinds
class Kind:
    """How one key's value is read, written and described."""

    text = "value"

    def decode(self, value, path: str):
        raise NotImplementedError

    def encode(self, value, path: str):
        raise NotImplementedError


def _number(value, path: str, what: str = "a number") -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _Fail(path, f"= {_show(value)} is not {what}: give {what}.")
    if not math.isfinite(value):
        raise _Fail(path, f"= {value!r} is not finite: give a finite number.")
    return float(value)


class Number(Kind):
    def __init__(self, unit: str = ""):
        self.unit = unit
        self.text = f"number [{unit}]" if unit else "number"

    def decode(self, value, path):
        return _number(value, path)

    def encode(self, value, path):
        return float(np.asarray(value))


class Integer(Kind):
    def __init__(self, low: int | None = None, text: str = "integer"):
        self.low, self.text = low, text

    def decode(self, value, path):
        if isinstance(value, bool) or not isinstance(value, int):
            raise _Fail(
                path, f"= {_show(value)} is not an integer: give a whole number."
            )
        if self.low is not None and value < self.low:
            raise _Fail(
                path, f"= {value} is below {self.low}: give {self.low} or more."
            )
        return value

    def encode(self, value, path):
        return int(value)


class Boolean(Kind):
    text = "true / false"

    def decode(self, value, path):
        if not isinstance(value, bool):
            raise _Fail(path, f"= {_show(value)} is not true or false.")
        return value

    def encode(self, value, path):
        return bool(value)


class String(Kind):
    def __init__(self, choices: tuple[str, ...] | None = None):
        self.choices = choices
        self.text = (
            " | ".join(f'"{c}"' for c in choices) if choices is not None else "string"
        )

    def decode(self, value, path):
        if not isinstance(value, str):
            raise _Fail(path, f"= {_show(value)} is not a string: give text in quotes.")
        if self.choices is not None and value not in self.choices:
            raise _Fail(
                path, f"= {value!r} is not one of {', '.join(map(repr, self.choices))}."
            )
        return value

    def encode(self, value, path):
        return str(value)


class Array(Kind):
    """A list (of lists) of numbers of a fixed shape; ``None`` in the shape: any."""

    def __init__(self, *shape: int | None, unit: str = ""):
        self.shape = shape
        dims = " x ".join("n" if s is None else str(s) for s in shape)
        self.text = f"{dims} numbers" + (f" [{unit}]" if unit else "")

    def decode(self, value, path):
        arr = _numeric_array(value, path)
        if len(self.shape) != arr.ndim or any(
            s is not None and s != n for s, n in zip(self.shape, arr.shape, strict=True)
        ):
            want = tuple("n" if s is None else s for s in self.shape)
            raise _Fail(
                path, f"= {_show(value)} has shape {arr.shape}: give shape {want}."
            )
        return arr.tolist()  # floats, as the constructors' messages show them

    def encode(self, value, path):
        return np.asarray(value, dtype=float).tolist()


def _numeric_array(value, path) -> np.ndarray:
    def check(v):
        if isinstance(v, list):
            return [check(x) for x in v]
        return _number(v, path, "a number (a list of numbers)")

    if not isinstance(value, list | int | float) or isinstance(value, bool):
        raise _Fail(path, f"= {_show(value)} is not a list of numbers.")
    try:
        arr = np.asarray(check(value), dtype=float)
    except ValueError:
        raise _Fail(
            path, f"= {_show(value)} is ragged: give rows of equal length."
        ) from None
    return arr


class Choice(Kind):
    """A matrix given as a scalar, a diagonal or a full matrix (joint stiffness)."""

    text = "number, list (diagonal) or matrix"

    def decode(self, value, path):
        return _numeric_array(value, path).tolist()

    def encode(self, value, path):
        m = np.asarray(value, dtype=float)
        if m.size == 0:
            return 0.0
        d = np.diag(m)
        if np.array_equal(m, np.diag(d)):
            return float(d[0]) if np.all(d == d[0]) else d.tolist()
        return m.tolist()


class Pose(Kind):
    """A 4x4 pose: the matrix, or ``{translation = [...], rotation = [[...]]}``."""

    text = "pose: {translation = [x, y, z], rotation = 3x3} or a 4x4 matrix"

    def decode(self, value, path):
        if isinstance(value, dict):
            unknown = set(value) - {"translation", "rotation"}
            if unknown:
                raise _Fail(
                    f"{path}.{sorted(unknown)[0]}",
                    "is not a key of a pose: give translation = [x, y, z] [m] "
                    "and/or rotation = a 3x3 rotation matrix.",
                )
            g = np.eye(4)
            if "translation" in value:
                g[:3, 3] = Array(3).decode(value["translation"], f"{path}.translation")
            if "rotation" in value:
                g[:3, :3] = Array(3, 3).decode(value["rotation"], f"{path}.rotation")
            return g
        return Array(4, 4).decode(value, path)

    def encode(self, value, path):
        g = np.asarray(value, dtype=float)
        if not np.array_equal(g[3], [0, 0, 0, 1]):
            return g.tolist()  # not a rigid pose: the matrix as it is
        if np.array_equal(g[:3, :3], np.eye(3)):
            return {"translation": g[:3, 3].tolist()}
        out = {"rotation": g[:3, :3].tolist()}
        if np.any(g[:3, 3]):
            out["translation"] = g[:3, 3].tolist()
        return out


class Profile(Kind):
    """A section dimension: a number, a taper ``[start, end]``, or a function."""

    text = 'number [m], [start, end] (a taper) or "module:function" of X1'

    def decode(self, value, path):
        if isinstance(value, str):
            return _import(value, path)
        if isinstance(value, list):
            arr = Array(2).decode(value, path)
            return (float(arr[0]), float(arr[1]))
        return _number(value, path)

    def encode(self, value, path):
        from ..model._profile import Constant, Custom, Linear

        if isinstance(value, Constant):
            return float(value.value)
        if isinstance(value, Linear):
            return [float(value.start), float(value.end)]
        if isinstance(value, Custom):
            return _callable_name(value.fn, path)
        raise _Fail(
            path, f"= {_show(value)}: a profile of unknown type cannot be saved."
        )


class Function(Kind):
    """A Python function: ``"module:function"``, or an ``equinox.Partial`` of one."""

    text = '"module:function" or {function = "module:function", args, kwargs}'

    def decode(self, value, path):
        if isinstance(value, str):
            return _import(value, path)
        if isinstance(value, dict):
            unknown = set(value) - {"function", "args", "kwargs"}
            if unknown or "function" not in value:
                raise _Fail(
                    path,
                    f'= {_show(value)}: give {{function = "module:function", args = '
                    "[...], kwargs = {...}}} (an equinox.Partial).",
                )
            import equinox as eqx

            fn = _import(String().decode(value["function"], f"{path}.function"), path)
            args = value.get("args", [])
            if not isinstance(args, list):
                raise _Fail(f"{path}.args", f"= {_show(args)} is not a list.")
            kwargs = value.get("kwargs", {})
            if not isinstance(kwargs, dict):
                raise _Fail(f"{path}.kwargs", f"= {_show(kwargs)} is not a table.")
            args = [
                _decode_argument(a, f"{path}.args[{i}]") for i, a in enumerate(args)
            ]
            kwargs = {
                k: _decode_argument(v, f"{path}.kwargs.{k}") for k, v in kwargs.items()
            }
            return eqx.Partial(fn, *args, **kwargs)
        raise _Fail(path, f'= {_show(value)}: give "module:function".')

    def encode(self, value, path):
        import equinox as eqx

        from ..model._hook import Hook

        if isinstance(value, Hook):
            value = value.function
        if isinstance(value, eqx.Partial):
            out: dict = {"function": _callable_name(value.func, path)}
            if value.args:
                out["args"] = [_encode_argument(a, path) for a in value.args]
            if value.keywords:
                out["kwargs"] = {
                    k: _encode_argument(v, path) for k, v in value.keywords.items()
                }
            return out
        return _callable_name(value, path)


def _decode_argument(value, path):
    """An argument of a saved ``equinox.Partial``: ``{array = ...}`` or plain."""
    if isinstance(value, dict):
        if set(value) != {"array"}:
            raise _Fail(path, f"= {_show(value)}: give {{array = [...]}} or a number.")
        import jax.numpy as jnp

        return jnp.asarray(_numeric_array(value["array"], f"{path}.array"))
    if isinstance(value, bool | int | float | str):
        return value
    raise _Fail(path, f"= {_show(value)}: give a number, a string or {{array = ...}}.")


def _encode_argument(value, path):
    if isinstance(value, bool | int | float | str):
        return value
    if hasattr(value, "shape") and hasattr(value, "dtype"):
        arr = np.asarray(value)
        if arr.dtype.kind == "f":
            return {"array": arr.tolist()}
    raise _Fail(
        path,
        f"holds the argument {_show(value)}: only numbers, strings and float arrays "
        "are saved; pass other values another way.",
    )


def _callable_name(fn, path: str) -> str:
    """``"module:qualname"`` of a module-level function that imports back to itself."""
    module = getattr(fn, "__module__", None)
    name = getattr(fn, "__qualname__", None)
    if module is None or name is None or "<" in name:
        raise _Fail(
            path,
            f"= {_show(fn)} is not a module-level function: a lambda, a closure or "
            "a callable object cannot be saved. Define it with def at the top of a "
            "module (use equinox.Partial for its parameters) and build the model "
            "with it.",
        )
    text = f"{module}:{name}"
    try:
        back = _import(text, path)
    except _Fail:
        back = None
    if back is not fn:
        raise _Fail(
            path,
            f"= {_show(fn)}: {text!r} does not import back to this function (a "
            "function of a script run as __main__, or one replaced since): move it "
            "to an importable module.",
        )
    return text


def _import(text: str, path: str):
    module, sep, name = text.partition(":")
    if not sep or not module or not name:
        raise _Fail(path, f'= {text!r}: name a function as "module:function".')
    try:
        obj = importlib.import_module(module)
    except Exception as err:  # noqa: BLE001 - any import failure names the module
        raise _Fail(
            path, f"= {text!r}: module {module!r} does not import ({err})."
        ) from None
    for part in name.split("."):
        if not hasattr(obj, part):
            raise _Fail(path, f"= {text!r}: module {module!r} has no {name!r}.")
        obj = getattr(obj, part)
    if not callable(obj):
        raise _Fail(path, f"= {text!r} is not callable.")
    return obj


class Table(Kind):
    """A nested table of one type (``spec``), or one of several by its ``type`` key."""

    def __init__(self, *specs: str):
        self.specs = specs
        self.text = " | ".join(specs) + " table"

    def decode(self, value, path):
        return _decode_table(self._spec_of(value, path), value, path)

    def _spec_of(self, value, path) -> Spec:
        if not isinstance(value, dict):
            raise _Fail(path, f"= {_show(value)} is not a table.")
        if len(self.specs) == 1:
            return SPECS[self.specs[0]]
        tags = {SPECS[s].tag: SPECS[s] for s in self.specs}
        if "type" not in value:
            raise _Fail(
                f"{path}.type", f"is missing: give one of {', '.join(map(repr, tags))}."
            )
        tag = value["type"]
        if tag not in tags:
            raise _Fail(
                f"{path}.type",
                f"= {_show(tag)} is not a type here: give one of "
                f"{', '.join(map(repr, tags))}.",
            )
        return tags[tag]

    def encode(self, value, path):
        for s in self.specs:
            spec = SPECS[s]
            if type(value) is spec.cls:
                return _encode_table(spec, value, path, typed=len(self.specs) > 1)
        names = ", ".join(SPECS[s].cls.__name__ for s in self.specs)
        raise _Fail(path, f"= {type(value).__name__}: only {names} can be saved here.")


class JointKind(Table):
    """A joint: a letter (``"R"``) or a ``[joint]`` table."""

    def __init__(self):
        super().__init__("joint")
        self.text = 'joint letter ("R") or joint table'

    def decode(self, value, path):
        if isinstance(value, str):
            value = {"type": value}
        return super().decode(value, path)

    def encode(self, value, path):
        out = super().encode(value, path)
        return out["type"] if list(out) == ["type"] else out


class ListOf(Kind):
    def __init__(self, item: Kind, text: str | None = None):
        self.item = item
        self.text = text or f"list of {item.text}"

    def decode(self, value, path):
        if not isinstance(value, list):
            raise _Fail(path, f"= {_show(value)} is not a list.")
        return tuple(self.item.decode(v, f"{path}[{i}]") for i, v in enumerate(value))

    def encode(self, value, path):
        return [self.item.encode(v, f"{path}[{i}]") for i, v in enumerate(value)]


class IntPair(Kind):
    text = "[a, b] (two link numbers)"

    def decode(self, value, path):
        if not (isinstance(value, list) and len(value) == 2):
            raise _Fail(path, f"= {_show(value)}: give two integers [a, b].")
        return tuple(Integer().decode(v, f"{path}[{i}]") for i, v in enumerate(value))

    def encode(self, value, path):
        return [int(v) for v in value]


class VectorOrFunction(Kind):
    """A fixed-length vector, or a function (a time-dependent wrench, a curved rod)."""

    def __init__(self, n: int | None, unit: str):
        self.n = n
        count = "list of" if n is None else f"{n}"
        self.text = f'{count} numbers [{unit}] or "module:function"'

    def decode(self, value, path):
        if isinstance(value, str | dict):
            return Function().decode(value, path)
        return Array(self.n).decode(value, path)

    def encode(self, value, path):
        if callable(value):
            return Function().encode(value, path)
        return Array(self.n).encode(value, path)


class Params(Kind):
    """A custom path's parameters: numbers, arrays or a table of them."""

    text = "number, list of numbers, or table of them"

    def decode(self, value, path):
        import jax.numpy as jnp

        if isinstance(value, dict):
            return {k: self.decode(v, f"{path}.{k}") for k, v in value.items()}
        return jnp.asarray(_numeric_array(value, path))

    def encode(self, value, path):
        if isinstance(value, dict):
            return {str(k): self.encode(v, f"{path}.{k}") for k, v in value.items()}
        if hasattr(value, "shape") or isinstance(value, int | float):
            return np.asarray(value, dtype=float).tolist()
        raise _Fail(path, f"= {_show(value)}: give numbers, arrays or a dict of them.")


# ============================================================== schema
@dataclasses.dataclass(frozen=True)
class Key:
    """One key of a table.

    Attributes:
        name: the key in the file (the constructor's argument of that name, unless
            ``arg`` says otherwise).
        kind: how its value is read and written.
        doc: what it is (for the key reference).
        default: the value when the key is omitted (text for the reference;
            :data:`REQUIRED` for a key that must be given).
        get: reads the value from a model object (default: the attribute ``name``);
            returning None omits the key.
        arg: the constructor argument it feeds (None: ``name``; ``""``: none: a
            table with such keys decodes to ``(object, {key: value})``, or its
            ``build`` reads them).
        omit: a written value equal to this is left out (the default's value).
    """

    name: str
    kind: Kind
    doc: str
    default: str = ""
    get: Callable | bool | None = None
    arg: str | None = None
    omit: Any = _ABSENT


@dataclasses.dataclass(frozen=True)
class Spec:
    """A table type: its class, its ``type`` tag (if one of several) and its keys."""

    name: str
    cls: type
    tag: str | None
    keys: tuple[Key, ...]
    doc: str
    build: Callable | None = None


SPECS: dict[str, Spec] = {}


def _spec(name, cls, tag, doc, *keys, build=None) -> None:
    SPECS[name] = Spec(name, cls, tag, keys, doc, build)


def _decode_table(spec: Spec, value, path: str):
    if not isinstance(value, dict):
        raise _Fail(path, f"= {_show(value)} is not a table.")
    known = {k.name for k in spec.keys} | ({"type"} if spec.tag else set())
    for key in value:
        if key not in known:
            hint = _near(key, known)
            raise _Fail(
                f"{path}.{key}" if path else key,
                f"is not a key of {spec.name} ({spec.cls.__name__})"
                + (f": did you mean {hint!r}?" if hint else "")
                + f" Keys: {', '.join(sorted(known))}.",
            )
    kwargs = {}
    for k in spec.keys:
        sub = f"{path}.{k.name}" if path else k.name
        if k.name not in value:
            if k.default == REQUIRED:
                raise _Fail(
                    sub, f"is missing: give {k.doc.rstrip('.')} ({k.kind.text})."
                )
            continue
        kwargs[k.name] = k.kind.decode(value[k.name], sub)
    try:
        if spec.build is not None:
            return spec.build(kwargs, path)
        args = {
            (k.arg or k.name): kwargs[k.name]
            for k in spec.keys
            if k.name in kwargs and k.arg != ""
        }
        obj = spec.cls(**args)
        extra = [k.name for k in spec.keys if k.arg == ""]
        return (obj, {k: kwargs[k] for k in extra if k in kwargs}) if extra else obj
    except _Fail:
        raise
    except (ValueError, TypeError) as err:
        raise _Fail(_field_path(spec, path, str(err)), str(err)) from None


def _field_path(spec: Spec, path: str, message: str) -> str:
    """The key a constructor's message names (``Division.length = ...``), or ``path``.

    The model's constructors name the field they refuse as ``Class.field[...]``;
    where that field is a key of the table, the error points at the key (and so at
    its line).
    """
    match = re.match(rf"{spec.cls.__name__}\.(\w+)((?:\[\d+\]|\.\w+)*)", message)
    if match and match.group(1) in {k.name for k in spec.keys}:
        field = match.group(1) + match.group(2)
        return f"{path}.{field}" if path else field
    return path or "(top level)"


def _near(key: str, known) -> str | None:
    import difflib

    close = difflib.get_close_matches(key, sorted(known), n=1, cutoff=0.7)
    return close[0] if close else None


def _encode_table(spec: Spec, obj, path: str, typed: bool) -> dict:
    out: dict = {"type": spec.tag} if typed else {}
    for k in spec.keys:
        if k.get is False:
            continue
        value = k.get(obj) if k.get is not None else getattr(obj, k.name)
        if value is None:
            continue
        sub = f"{path}.{k.name}" if path else k.name
        encoded = k.kind.encode(value, sub)
        if k.omit is not _ABSENT and encoded == k.omit:
            continue
        out[k.name] = encoded
    return out


def _define() -> None:
    """Fill :data:`SPECS` (at import: the model classes are imported here)."""
    from .. import model as m
    from ..model._link import XI_STRAIGHT, default_n_gauss

    length, metre = "m", "m"
    pose_doc = "identity"
    # ------------------------------------------------------------- pieces
    _spec(
        "joint",
        m.Joint,
        None,
        "A lumped joint (the manual's joint dialog): a letter alone, `joint = "
        '"R"`, or a table.',
        Key(
            "type",
            String(tuple("NRPHUCASF")),
            "the joint type: N fixed, R revolute, P prismatic, H helical, U "
            "universal, C cylindrical, A planar, S spherical, F free",
            "N",
            get=lambda j: j.kind,
            arg="kind",
        ),
        Key(
            "axis",
            Array(3),
            "axis in the joint frame (normalised)",
            "x (z for A)",
            get=_joint_axis,
        ),
        Key("pitch", Number("m/rad"), "helical pitch (H)", "0", omit=0.0),
        Key(
            "stiffness",
            Choice(),
            "stiffness per freedom [N m/rad or N/m]: scalar, diagonal or matrix",
            "0",
            omit=0.0,
        ),
        Key(
            "damping",
            Choice(),
            "damping per freedom: scalar, diagonal or matrix",
            "0",
            omit=0.0,
        ),
    )
    _spec(
        "material",
        m.Material,
        None,
        "A soft link's material (linear elastic, Kelvin-Voigt damping).",
        Key("E", Number("Pa"), "Young's modulus", REQUIRED),
        Key("poisson", Number(), "Poisson ratio, in (-1, 0.5]", "0.5", omit=0.5),
        Key("rho", Number("kg/m^3"), "density", "1000", omit=1000.0),
        Key("eta", Number("Pa s"), "material damping", "0", omit=0.0),
    )
    mech = (
        Key(
            "torsion",
            String(("saint-venant", "polar")),
            "torsion constant model (polar: J = Iy + Iz, SoRoSim's)",
            "saint-venant",
            omit="saint-venant",
        ),
        Key(
            "shear_coefficient",
            Number(),
            "shear coefficient in (0, 1.5] (1: SoRoSim's); omitted: Cowper's",
            "Cowper's",
        ),
    )
    _spec(
        "section.circular",
        m.CircularSection,
        "circular",
        "A solid circle.",
        Key("radius", Profile(), "radius", REQUIRED),
        *mech,
    )
    _spec(
        "section.rectangular",
        m.RectangularSection,
        "rectangular",
        "A solid rectangle, width along y, height along z.",
        Key("height", Profile(), "height along z", REQUIRED),
        Key("width", Profile(), "width along y", REQUIRED),
        *mech,
    )
    _spec(
        "section.elliptical",
        m.EllipticalSection,
        "elliptical",
        "A solid ellipse, semi-axis a along y, b along z.",
        Key("a", Profile(), "semi-axis along y", REQUIRED),
        Key("b", Profile(), "semi-axis along z", REQUIRED),
        *mech,
    )
    _spec(
        "section.annular",
        m.AnnularSection,
        "annular",
        "A hollow circle (a tube) between an inner and an outer radius.",
        Key("outer", Profile(), "outer radius", REQUIRED),
        Key("inner", Profile(), "inner radius (below outer)", REQUIRED),
        *mech,
    )
    _spec(
        "section.properties",
        m.SectionProperties,
        "properties",
        "A section given by its properties (measured, or from a section solver).",
        Key("A", Profile(), "area [m^2]", REQUIRED),
        Key("Iy", Profile(), "second moment about y [m^4]", REQUIRED),
        Key("Iz", Profile(), "second moment about z [m^4]", REQUIRED),
        Key("J", Profile(), "torsion constant [m^4]", REQUIRED),
        Key("shear_area_y", Profile(), "k_y A [m^2]", "A"),
        Key("shear_area_z", Profile(), "k_z A [m^2]", "A"),
        Key(
            "polar_moment",
            Profile(),
            "polar moment for rotary inertia [m^4]",
            "Iy + Iz",
        ),
    )
    sections = tuple(s for s in SPECS if s.startswith("section."))

    def orders_of(b):
        first = next((o for mo, o in zip(b.modes, b.orders, strict=True) if mo), 0)
        if type(b)(b.modes, first).orders == b.orders:
            return first
        return list(b.orders)

    poly = (
        Key(
            "modes",
            Flags(),
            "six 0/1 flags: torsion, bend y, bend z, elongation, shear y, shear z",
            "[1, 1, 1, 0, 0, 0]",
            get=lambda b: list(b.modes),
        ),
        Key(
            "orders",
            Orders(),
            "polynomial order per mode (one integer for all)",
            "0",
            get=orders_of,
        ),
    )
    _spec(
        "basis.legendre",
        m.LegendreBasis,
        "legendre",
        "Shifted Legendre polynomials (default).",
        *poly,
    )
    _spec(
        "basis.monomial",
        m.MonomialBasis,
        "monomial",
        "Monomials 1, X1, X1^2, ... (the manual's tables).",
        *poly,
    )
    _spec(
        "basis.custom",
        m.CustomBasis,
        "custom",
        "A user basis: a function X1 -> (6, dofs) array.",
        Key(
            "function",
            Function(),
            "the basis function",
            REQUIRED,
            get=lambda b: b.fn,
            arg="fn",
        ),
        Key("dofs", Integer(0), "number of columns", REQUIRED),
        Key(
            "order",
            Integer(0),
            "polynomial degree for the default quadrature",
            "3",
            omit=3,
        ),
    )
    _spec(
        "basis.padded",
        m.PaddedBasis,
        "padded",
        "A polynomial basis padded to a size class (sorojax.size_class).",
        Key(
            "basis",
            Table("basis.legendre", "basis.monomial"),
            "the class's basis",
            REQUIRED,
        ),
        Key(
            "active",
            Array(None),
            "1 for the model's own columns, 0 for padding",
            REQUIRED,
        ),
        build=_padded,
    )
    bases = ("basis.legendre", "basis.monomial", "basis.custom", "basis.padded")
    _spec(
        "division",
        m.Division,
        None,
        "One division of a soft link (`[[links.divisions]]`).",
        Key("length", Number(length), "length", REQUIRED),
        Key("section", Table(*sections), "cross-section", "circular, radius 0.01"),
        Key(
            "basis",
            Table(*bases),
            "strain basis",
            "legendre, modes [1, 1, 1, 0, 0, 0], order 0",
        ),
        Key(
            "n_gauss",
            Integer(1),
            "interior Gauss points",
            "max(8, 2 order + 4)",
            get=lambda d: (
                None if d.n_gauss == default_n_gauss(d.basis.max_order) else d.n_gauss
            ),
        ),
        Key(
            "xi_ref",
            VectorOrFunction(6, "1/m, -"),
            "reference strain (a 6-vector or a function of X1)",
            "[0, 0, 0, 1, 0, 0] (straight)",
            omit=list(XI_STRAIGHT),
        ),
    )
    link_common = (
        Key(
            "parent",
            Integer(0),
            "number of the link whose tip this link is attached "
            "to (0: ground; links are numbered from 1 in file order)",
            "the previous link",
            get=False,
            arg="",
        ),
        Key(
            "placement",
            Pose(),
            "pose of the link's base in the parent's tip frame (the manual's g_ini)",
            pose_doc,
            get=False,
            arg="",
        ),
    )
    _spec(
        "links.soft",
        m.SoftLink,
        "soft",
        "A soft link: a joint followed by a Cosserat rod of one or more divisions.",
        *link_common,
        Key("joint", JointKind(), "the joint at the base", '"N" (fixed)', omit="N"),
        Key("material", Table("material"), "material", REQUIRED),
        Key(
            "divisions",
            ListOf(Table("division"), "list of division tables"),
            "the divisions",
            REQUIRED,
        ),
        Key(
            "g_i",
            Pose(),
            "rod start in the joint frame",
            pose_doc,
            omit={"translation": [0.0, 0.0, 0.0]},
        ),
        Key(
            "g_f",
            Pose(),
            "tip reference point in the rod's end frame",
            pose_doc,
            omit={"translation": [0.0, 0.0, 0.0]},
        ),
        Key(
            "color", String(), "plot colour (matplotlib)", '"tab:blue"', omit="tab:blue"
        ),
    )
    _spec(
        "links.rigid",
        m.RigidLink,
        "rigid",
        "A rigid link: a joint followed by a rigid body (a prism of `length` and "
        "`section`, or a given mass and inertia).",
        *link_common,
        Key("joint", JointKind(), "the joint at the base", '"N" (fixed)', omit="N"),
        Key("length", Number(metre), "length along x", "0.1", omit=0.1),
        Key(
            "section",
            Table(*sections),
            "cross-section of the prism",
            "circular, radius 0.01",
        ),
        Key("rho", Number("kg/m^3"), "density", "1000", omit=1000.0),
        Key("mass", Number("kg"), "mass", "from the shape"),
        Key(
            "inertia",
            Array(3, 3, unit="kg m^2"),
            "rotational inertia at the CM",
            "from the shape",
        ),
        Key(
            "g_i",
            Pose(),
            "joint -> CM pose",
            "translation L/2 along x",
            get=lambda lk: lk.g_i_,
        ),
        Key(
            "g_f",
            Pose(),
            "CM -> tip pose",
            "translation L/2 along x",
            get=lambda lk: lk.g_f_,
        ),
        Key("color", String(), "plot colour", '"tab:gray"', omit="tab:gray"),
    )
    _spec(
        "point_wrenches",
        m.PointWrench,
        None,
        "A point wrench (`[[point_wrenches]]`): the manual's point force/moment.",
        Key("link", Integer(1), "link number (from 1)", REQUIRED),
        Key(
            "wrench",
            VectorOrFunction(6, "N m, N"),
            "(moment, force), or a function of t",
            REQUIRED,
        ),
        Key(
            "division",
            Integer(1),
            "division of a soft link (omitted: its tip)",
            "the tip",
        ),
        Key("X1", Number(), "position in the division, in [0, 1]", "1", omit=1.0),
        Key(
            "follower",
            Boolean(),
            "turns with the body (local frame)",
            "false",
            omit=False,
        ),
        Key(
            "at_tip",
            Boolean(),
            "on a rigid link: at the tip, not the CM",
            "false",
            omit=False,
        ),
    )
    _spec(
        "path.constant",
        m.ConstantPath,
        "constant",
        "Constant offset (y, z) in the section.",
        Key("y", Number(metre), "offset along y", "0", omit=0.0),
        Key("z", Number(metre), "offset along z", "0", omit=0.0),
    )
    _spec(
        "path.oblique",
        m.ObliquePath,
        "oblique",
        "Offset linear in X from start to end.",
        Key("start", Array(2, unit="m"), "(y, z) at X = 0", REQUIRED),
        Key("end", Array(2, unit="m"), "(y, z) at X = 1", REQUIRED),
    )
    _spec(
        "path.helical",
        m.HelicalPath,
        "helical",
        "A helix about the centre line.",
        Key("radius", Number(metre), "helix radius", REQUIRED),
        Key("turns", Number(), "turns over the link (> 0: right-handed)", REQUIRED),
        Key("phase", Number("rad"), "angle at X = 0", "0", omit=0.0),
    )
    _spec(
        "path.custom",
        m.CustomPath,
        "custom",
        "A user path: a function (X, params) -> (y, z).",
        Key(
            "function",
            Function(),
            "the path function",
            REQUIRED,
            get=lambda p: p.fn,
            arg="fn",
        ),
        Key("params", Params(), "its parameters (arrays)", "none"),
    )
    paths = ("path.constant", "path.oblique", "path.helical", "path.custom")
    _spec(
        "route.span",
        m.CableSpan,
        "span",
        "The part of a cable inside a soft link.",
        Key("link", Integer(1), "soft link number", REQUIRED),
        Key("path", Table(*paths), "the path in the section", REQUIRED),
        Key(
            "divisions",
            IntPair(),
            "[first, last] divisions spanned",
            "all",
            get=lambda s: None if s.divisions is None else list(s.divisions),
        ),
    )
    _spec(
        "route.anchor",
        m.CableAnchor,
        "anchor",
        "A point a cable passes through, fixed to a link or the ground.",
        Key("link", Integer(0), "link number, 0 for the ground", REQUIRED),
        Key(
            "offset",
            Array(3, unit="m"),
            "position in that point's frame (world for the ground)",
            "[0, 0, 0]",
            omit=[0.0, 0.0, 0.0],
        ),
        Key("division", Integer(1), "division of a soft link", "the tip"),
        Key("X1", Number(), "position in the division", "1", omit=1.0),
        Key("at_tip", Boolean(), "a rigid link's tip, not its CM", "false", omit=False),
    )
    _spec(
        "actuators.joint",
        m.JointActuator,
        "joint",
        "Actuation of a link's joint: by force, or by prescribed coordinates.",
        Key("link", Integer(1), "link number", REQUIRED),
        Key(
            "prescribed",
            Boolean(),
            "inputs are the joint coordinates (the manual's Q), efforts solved for",
            "false",
            omit=False,
        ),
    )
    _spec(
        "actuators.cable",
        m.Cable,
        "cable",
        "A cable: input its tension [N], > 0 pulls (SoRoSim's sign is opposite).",
        Key(
            "route",
            ListOf(
                Table("route.span", "route.anchor"),
                "list of route.span / route.anchor tables",
            ),
            "spans and anchors, in order",
            REQUIRED,
        ),
        Key("name", String(), "label", '"cable"', omit="cable"),
    )
    _spec(
        "closed_loops",
        m.ClosedLoopJoint,
        None,
        "A joint closing a loop between two link tips (`[[closed_loops]]`).",
        Key("joint", JointKind(), "the joint (its stiffness is not used)", REQUIRED),
        Key("link_A", Integer(1), "link A", REQUIRED),
        Key("link_B", Integer(0), "link B (0: ground)", "0", omit=0),
        Key(
            "g_A",
            Pose(),
            "joint frame in A's tip frame",
            pose_doc,
            omit={"translation": [0.0, 0.0, 0.0]},
        ),
        Key(
            "g_B",
            Pose(),
            "joint frame in B's tip frame (world for ground)",
            pose_doc,
            omit={"translation": [0.0, 0.0, 0.0]},
        ),
    )
    _spec(
        "law",
        m.ContactLaw,
        None,
        "A contact law (`[contact.law]`, or an obstacle's own `law`).",
        Key("stiffness", Number("N/m^2 on rods, N/m per point"), "k", REQUIRED),
        Key(
            "smoothing",
            Number(metre),
            "ramp depth (penalty) or reach (barrier)",
            "1e-4",
            omit=1e-4,
        ),
        Key("damping", Number(), "normal damping", "0", omit=0.0),
        Key("static_friction", Number(), "mu_s", "0", omit=0.0),
        Key(
            "kinetic_friction",
            Number(),
            "mu_k",
            "mu_s",
            get=lambda lw: (
                None
                if float(lw.kinetic_friction) == float(lw.static_friction)
                else lw.kinetic_friction
            ),
        ),
        Key("stick_velocity", Number("m/s"), "v_s", "1e-3", omit=1e-3),
        Key("stribeck_velocity", Number("m/s"), "Stribeck speed", "1e-2", omit=1e-2),
        Key("forward_friction", Number(), "mu_f along +x (anisotropic)", "none"),
        Key(
            "stick_load",
            Number("N/m on rods, N per point"),
            "f*: the stick velocity grows past it",
            "none",
        ),
        Key(
            "kind",
            String(("penalty", "barrier")),
            "normal law",
            '"penalty"',
            omit="penalty",
        ),
    )
    obstacle_common = (
        Key(
            "pose",
            Pose(),
            "obstacle frame in the world",
            pose_doc,
            omit={"translation": [0.0, 0.0, 0.0]},
        ),
        Key(
            "motion",
            Function(),
            "a function t -> pose (a moving obstacle)",
            "none",
            get=lambda o: o.motion,
        ),
        Key(
            "law",
            Table("law"),
            "this obstacle's own law",
            "the contact's",
            get=False,
            arg="",
        ),
    )
    _spec(
        "obstacles.plane",
        m.Plane,
        "plane",
        "A half-space (a floor).",
        Key(
            "point",
            Array(3, unit="m"),
            "a point of the plane",
            "[0, 0, 0]",
            omit=[0.0, 0.0, 0.0],
        ),
        Key("normal", Array(3), "outward normal", "[0, 0, 1]", omit=[0.0, 0.0, 1.0]),
        *obstacle_common,
        Key("name", String(), "label", '"plane"', omit="plane"),
    )
    _spec(
        "obstacles.sphere",
        m.Sphere,
        "sphere",
        "A solid sphere.",
        Key("radius", Number(metre), "radius", REQUIRED),
        Key("centre", Array(3, unit="m"), "centre", "[0, 0, 0]", omit=[0.0, 0.0, 0.0]),
        *obstacle_common,
        Key("name", String(), "label", '"sphere"', omit="sphere"),
    )
    _spec(
        "obstacles.capsule",
        m.Capsule,
        "capsule",
        "A capsule (a rounded rod).",
        Key("radius", Number(metre), "radius", REQUIRED),
        Key(
            "start",
            Array(3, unit="m"),
            "axis start",
            "[0, 0, -1]",
            omit=[0.0, 0.0, -1.0],
        ),
        Key("end", Array(3, unit="m"), "axis end", "[0, 0, 1]", omit=[0.0, 0.0, 1.0]),
        *obstacle_common,
        Key("name", String(), "label", '"capsule"', omit="capsule"),
    )
    _spec(
        "obstacles.box",
        m.Box,
        "box",
        "A box centred in its frame.",
        Key("half_extents", Array(3, unit="m"), "half lengths", REQUIRED),
        *obstacle_common,
        Key("name", String(), "label", '"box"', omit="box"),
    )
    link_key = Key(
        "link", Integer(1), "the rigid link it belongs to", REQUIRED, get=False, arg=""
    )
    _spec(
        "shapes.sphere",
        m.ContactSphere,
        "sphere",
        "A contact sphere of a rigid link (CM frame).",
        link_key,
        Key("radius", Number(metre), "radius", REQUIRED),
        Key("centre", Array(3, unit="m"), "centre", "[0, 0, 0]", omit=[0.0, 0.0, 0.0]),
    )
    _spec(
        "shapes.capsule",
        m.ContactCapsule,
        "capsule",
        "A contact capsule along a rigid link's CM x axis.",
        link_key,
        Key("length", Number(metre), "axis length", REQUIRED),
        Key("radius", Number(metre), "radius", REQUIRED),
        Key("n_samples", Integer(2), "spheres along the axis", "from the length"),
    )
    _spec(
        "shapes.box",
        m.ContactBox,
        "box",
        "A contact box centred at a rigid link's CM.",
        link_key,
        Key("half_extents", Array(3, unit="m"), "half lengths", REQUIRED),
    )
    _spec(
        "radius",
        dict,
        None,
        "A soft link's contact radius override.",
        Key("link", Integer(1), "soft link number", REQUIRED),
        Key("radius", Number(metre), "contact radius", REQUIRED),
        build=lambda kw, p: (kw["link"], kw["radius"]),
    )
    obstacles = tuple(s for s in SPECS if s.startswith("obstacles."))
    shapes = ("shapes.sphere", "shapes.capsule", "shapes.box")
    _spec(
        "contact",
        m.Contact,
        None,
        "Contact (`[contact]`): obstacles, the law, rod pairs, self-contact, tubes.",
        Key("law", Table("law"), "the contact law", REQUIRED),
        Key(
            "obstacles",
            ListOf(Table(*obstacles), "list of obstacle tables"),
            "obstacles",
            "none",
            get=lambda c: c.obstacles or None,
        ),
        Key(
            "links",
            ListOf(Integer(1), "list of link numbers"),
            "links that touch the obstacles",
            "all soft links and rigid links with a shape",
        ),
        Key(
            "shapes",
            ListOf(Table(*shapes), "list of shape tables"),
            "rigid links' contact shapes",
            "none",
            get=False,
            arg="",
        ),
        Key(
            "radius",
            ListOf(Table("radius"), "list of radius tables"),
            "soft links' contact radii",
            "the sections'",
            get=False,
            arg="",
        ),
        Key(
            "spacing",
            Number(metre),
            "largest distance between samples",
            "from the radii",
        ),
        Key(
            "rod_pairs",
            ListOf(IntPair(), "list of [a, b]"),
            "links checked against each other",
            "none",
            get=lambda c: c.rod_pairs or None,
        ),
        Key(
            "self_contact",
            ListOf(Integer(1), "list of link numbers"),
            "soft links checked against themselves",
            "none",
            get=lambda c: c.self_contact or None,
        ),
        Key(
            "friction_in_rod_pairs",
            Boolean(),
            "rod-rod contacts carry friction",
            "true",
            omit=True,
        ),
        Key(
            "inside",
            ListOf(IntPair(), "list of [tube, body]"),
            "bodies inside tubes",
            "none",
            get=lambda c: c.inside or None,
        ),
        Key(
            "tangent_in_w",
            Boolean(),
            "ROS34PW2's W carries the contact tangent",
            "true",
            omit=True,
        ),
        Key(
            "pair_capacity",
            Integer(1),
            "segment pairs per rod pair (broad phase)",
            "4 per segment",
        ),
        build=_build_contact,
    )
    _spec(
        "statics",
        dict,
        None,
        "Default inputs and settings of `sorojax statics` (solve_statics's arguments).",
        Key("u", Array(None), "actuation inputs in actuator order", "zeros"),
        Key("q0", Array(None), "initial guess", "zeros"),
        Key("t", Number("s"), "time of time-dependent loads", "0"),
        Key("load_steps", Integer(1), "load steps", "automatic"),
        Key("max_load_steps", Integer(1), "most automatic load steps", "16"),
        Key("load_increment", Number(), "largest coordinate change per iteration", "2"),
        Key("max_steps", Integer(1), "Newton iterations per load step", "64"),
        Key("rtol", Number(), "relative tolerance", "1e-10"),
        Key("atol", Number(), "absolute tolerance", "1e-10"),
        build=lambda kw, p: kw,
    )
    _spec(
        "simulate",
        dict,
        None,
        "Default settings of `sorojax simulate` (simulate's arguments).",
        Key("t1", Number("s"), "final time", "1"),
        Key("t0", Number("s"), "initial time", "0"),
        Key("q0", Array(None), "initial coordinates", "zeros"),
        Key("qd0", Array(None), "initial velocities", "zeros"),
        Key(
            "u",
            VectorOrFunction(None, "-"),
            "inputs: constant, or a function t -> u",
            "zeros",
        ),
        Key("n_save", Integer(2), "saved times", "101"),
        Key("solver", String(), "integrator name (sorojax.SOLVERS)", '"auto"'),
        Key("rtol", Number(), "relative tolerance", "1e-3"),
        Key("atol", Number(), "absolute tolerance", "1e-5"),
        Key("dt0", Number("s"), "initial (or fixed) step", "automatic"),
        Key("adaptive", Boolean(), "adaptive steps", "the solver's"),
        Key("max_steps", Integer(1), "most steps", "16384"),
        Key(
            "controller_gains",
            Array(2),
            "(pcoeff, icoeff) of the step-size controller",
            "the solver's",
        ),
        build=lambda kw, p: kw,
    )
    _spec(
        "scene",
        m.Linkage,
        None,
        "The top level of a scene file.",
        Key("format", String((FORMAT,)), "the file format", REQUIRED, get=False),
        Key("version", Integer(1), f"format version ({VERSION})", REQUIRED, get=False),
        Key("description", String(), "what the scene is", "none", get=False),
        Key(
            "gravity",
            Array(3, unit="m/s^2"),
            "gravitational acceleration in the world frame",
            "[0, 0, 0]",
            omit=[0.0, 0.0, 0.0],
        ),
        Key(
            "baumgarte_time",
            Number("s"),
            "closed loops' Baumgarte time constant",
            "0.01",
            omit=0.01,
        ),
        Key(
            "custom_wrench",
            Function(),
            "hook (t, q, qd, kinematics) -> wrenches",
            "none",
        ),
        Key(
            "custom_actuation",
            Function(),
            "hook (t, q, qd, kinematics, u) -> actuation wrenches",
            "none",
        ),
        Key(
            "actuator_strength",
            Function(),
            "hook (t, q, qd, kinematics) -> u (feedback control)",
            "none",
        ),
        Key(
            "added_mass",
            Array(None, 6, 6),
            "added inertia per significant point",
            "none",
        ),
        Key(
            "links",
            ListOf(
                Table("links.soft", "links.rigid"),
                "list of links.soft / links.rigid tables",
            ),
            "the links, numbered from 1 in this order",
            REQUIRED,
            get=False,
        ),
        Key(
            "point_wrenches",
            ListOf(Table("point_wrenches"), "list of point_wrenches tables"),
            "point wrenches",
            "none",
            get=lambda lk: lk.point_wrenches or None,
        ),
        Key(
            "actuators",
            ListOf(
                Table("actuators.joint", "actuators.cable"),
                "list of actuators.joint / actuators.cable tables",
            ),
            "actuators, each owning a block of u in this order",
            "none",
            get=lambda lk: lk.actuators or None,
        ),
        Key(
            "closed_loops",
            ListOf(Table("closed_loops"), "list of closed_loops tables"),
            "closed-loop joints",
            "none",
            get=lambda lk: lk.closed_loops or None,
        ),
        Key("contact", Table("contact"), "contact", "none"),
        Key(
            "statics",
            Table("statics"),
            "settings of `sorojax statics`",
            "none",
            get=False,
        ),
        Key(
            "simulate",
            Table("simulate"),
            "settings of `sorojax simulate`",
            "none",
            get=False,
        ),
        build=_build_scene,
    )


class Flags(Kind):
    text = "six 0/1 flags"

    def decode(self, value, path):
        if not isinstance(value, list) or len(value) != 6:
            raise _Fail(path, f"= {_show(value)}: give six 0/1 flags.")
        return tuple(Integer().decode(v, f"{path}[{i}]") for i, v in enumerate(value))

    def encode(self, value, path):
        return [int(v) for v in value]


class Orders(Kind):
    text = "integer, or six integers"

    def decode(self, value, path):
        if isinstance(value, list):
            return tuple(
                Integer(0).decode(v, f"{path}[{i}]") for i, v in enumerate(value)
            )
        return Integer(0).decode(value, path)

    def encode(self, value, path):
        return value


def _padded(kw: dict, path: str):
    import jax.numpy as jnp

    from ..model import PaddedBasis

    return PaddedBasis(kw["basis"], jnp.asarray(kw["active"], dtype=float))


def _joint_axis(joint):
    """A joint's axis, or None where it is the default (x; z for ``A``) or has none."""
    if joint.kind in "NSF":
        return None
    axis = [float(x) for x in joint.axis]
    return (
        None
        if axis == ([0.0, 0.0, 1.0] if joint.kind == "A" else [1.0, 0.0, 0.0])
        else axis
    )


def _build_contact(kw: dict, path: str):
    from ..model import Contact

    args = {k: v for k, v in kw.items() if k not in ("shapes", "radius", "obstacles")}
    obstacles = tuple(ob for ob, _ in kw.get("obstacles", ()))
    laws = {i: x["law"] for i, (_, x) in enumerate(kw.get("obstacles", ())) if x}
    shapes = {}
    for i, (shape, extra) in enumerate(kw.get("shapes", ())):
        link = extra["link"]
        if link in shapes:
            raise _Fail(
                f"{path}.shapes[{i}].link", f"= {link}: this link already has a shape."
            )
        shapes[link] = shape
    radius = dict(kw.get("radius", ()))
    return Contact(obstacles, shapes=shapes, radius=radius, obstacle_laws=laws, **args)


def _build_scene(kw: dict, path: str):
    from ..model import Linkage

    links = [link for link, _ in kw["links"]]
    parents = [x.get("parent", i) for i, (_, x) in enumerate(kw["links"])]
    n = len(links)
    for i, p in enumerate(parents):
        if not 0 <= p <= n:
            raise _Fail(
                f"links[{i}].parent",
                f"= {p} is out of range: give 0 (ground) or a link number 1..{n}.",
            )
        if p >= i + 1:
            raise _Fail(
                f"links[{i}].parent",
                f"= {p}: link {i + 1} must hang from the ground or an earlier link "
                f"(1..{i}); list links parents first (this also rules out cycles).",
            )
    placements = np.stack([x.get("placement", np.eye(4)) for _, x in kw["links"]])
    args = {
        k: kw[k]
        for k in (
            "gravity",
            "baumgarte_time",
            "custom_wrench",
            "custom_actuation",
            "actuator_strength",
            "added_mass",
            "point_wrenches",
            "actuators",
            "closed_loops",
            "contact",
        )
        if k in kw
    }
    linkage = Linkage(links, parents=parents, placements=placements, **args)
    return linkage, kw.get("statics", {}), kw.get("simulate", {})


def _ensure_specs() -> None:
    if not SPECS:
        _define()


# ============================================================== lines of keys
_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEYLINE = re.compile(r"^\s*([A-Za-z0-9_\-\"'.]+)\s*=")


def _key_lines(text: str) -> dict[str, int]:
    """Map each key's path (``links[0].divisions[1].length``) to its 1-based line.

    Headers (``[a.b]``, ``[[a.b]]``) and ``key = value`` lines at the start of a
    line; inline tables and multi-line arrays map to the line of their key.
    """
    lines: dict[str, int] = {}
    counts: dict[str, int] = {}
    current = ""
    depth = 0

    def resolve(parts: list[str]) -> str:
        out = ""
        for part in parts:
            out = f"{out}.{part}" if out else part
            if out in counts:
                out = f"{out}[{counts[out]}]"
        return out

    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.split("#", 1)[0] if '"' not in line else line
        if depth == 0:
            head = _HEADER.match(line)
            if head:
                parts = [p.strip().strip("\"'") for p in head.group(2).split(".")]
                if head.group(1) == "[[":
                    parent = resolve(parts[:-1])
                    full = f"{parent}.{parts[-1]}" if parent else parts[-1]
                    counts[full] = counts.get(full, -1) + 1
                    current = f"{full}[{counts[full]}]"
                else:
                    current = resolve(parts)
                lines.setdefault(current, number)
                continue
            key = _KEYLINE.match(line)
            if key:
                name = ".".join(p.strip("\"'") for p in key.group(1).split("."))
                lines.setdefault(f"{current}.{name}" if current else name, number)
        depth += stripped.count("[") - stripped.count("]")
        depth = max(depth, 0)
    return lines


def _line_of(lines: dict[str, int], path: str) -> int | None:
    while path:
        if path in lines:
            return lines[path]
        cut = max(path.rfind("."), path.rfind("["))
        if cut <= 0:
            break
        path = path[:cut]
    return lines.get(path)


# ============================================================== public API
@dataclasses.dataclass(frozen=True)
class Scene:
    """A scene file read: the linkage and the settings of its statics and dynamics.

    Attributes:
        linkage: the model.
        statics: keyword arguments of :func:`~sorojax.solve_statics` from
            ``[statics]`` (``u``, ``q0`` and the solver settings).
        simulate: keyword arguments of :func:`~sorojax.simulate` from ``[simulate]``
            (``t1`` included).
        description: the file's description.
        path: the file read (None for text).
    """

    linkage: Any
    statics: dict
    simulate: dict
    description: str
    path: Any = None


def loads_scene(text: str, name: str = "<string>") -> Scene:
    """Read a scene from TOML text (``name`` is used in error messages)."""
    _ensure_specs()
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        match = re.search(r"line (\d+)", str(err))
        raise SceneError(
            name,
            "",
            f"not valid TOML: {err}",
            int(match.group(1)) if match else None,
        ) from None
    lines = _key_lines(text)
    try:
        if raw.get("format") != FORMAT:
            if "format" not in raw:
                raise _Fail(
                    "format",
                    f'is missing: a scene file starts with format = "{FORMAT}".',
                )
            raise _Fail(
                "format", f'= {_show(raw["format"])}: give format = "{FORMAT}".'
            )
        if (
            "version" in raw
            and isinstance(raw["version"], int)
            and raw["version"] != VERSION
        ):
            raise _Fail(
                "version",
                f"= {raw['version']}: this sorojax reads scene format version "
                f"{VERSION}; upgrade sorojax for a newer file.",
            )
        linkage, statics, simulate = _decode_table(SPECS["scene"], raw, "")
    except _Fail as fail:
        raise SceneError(
            name, fail.path, fail.message, _line_of(lines, fail.path)
        ) from None
    return Scene(
        linkage=linkage,
        statics=dict(statics),
        simulate=dict(simulate),
        description=raw.get("description", ""),
    )


def load_scene(path: str | os.PathLike) -> Scene:
    """Read a scene file: the linkage and its ``[statics]`` and ``[simulate]`` settings.

    Raises:
        SceneError: the file is not a valid scene (the message names the file, the
            key and its line, the value and the fix).
        FileNotFoundError: no such file.
    """
    p = as_path(path)
    text = p.read_text(encoding="utf-8")
    return dataclasses.replace(loads_scene(text, str(p)), path=p)


def load_linkage(path: str | os.PathLike):
    """Read the :class:`~sorojax.Linkage` of a scene file (see :func:`load_scene`)."""
    return load_scene(path).linkage


def dumps_scene(
    linkage,
    *,
    statics: dict | None = None,
    simulate: dict | None = None,
    description: str | None = None,
) -> str:
    """The TOML text of a scene (see :func:`save_linkage`)."""
    import tomlkit

    _ensure_specs()
    try:
        data = _encode_scene(linkage)
        for key, settings in (("statics", statics), ("simulate", simulate)):
            if settings:
                data[key] = _encode_settings(key, settings)
    except _Fail as fail:
        raise ValueError(
            f"cannot save the linkage: {fail.path} {fail.message}"
        ) from None
    doc = tomlkit.document()
    doc.add(tomlkit.comment("sorojax scene file: the keys are listed in the docs,"))
    doc.add(
        tomlkit.comment("guide/scene-files.md. Check it with `sorojax check FILE`.")
    )
    doc.add("format", FORMAT)
    doc.add("version", VERSION)
    if description:
        doc.add("description", description)
    for key, value in data.items():
        if not isinstance(value, dict | list) or (
            isinstance(value, list) and not (value and isinstance(value[0], dict))
        ):
            doc.add(key, _inline(value))
    for key, value in data.items():
        if isinstance(value, dict):
            doc.add(tomlkit.nl())
            doc.add(key, _table(value))
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            doc.add(tomlkit.nl())
            doc.add(key, _aot(value))
    return tomlkit.dumps(doc)


def _inline(value):
    import tomlkit

    if isinstance(value, dict):
        t = tomlkit.inline_table()
        for k, v in value.items():
            t[k] = _inline(v)
        return t
    if isinstance(value, list):
        arr = tomlkit.array()
        arr.extend(_inline(v) for v in value)
        return arr
    return value


_SUBTABLES = {"divisions", "route", "obstacles", "shapes", "radius", "law"}


def _table(value: dict):
    import tomlkit

    t = tomlkit.table()
    for k, v in value.items():
        if isinstance(v, list) and v and isinstance(v[0], dict) and k in _SUBTABLES:
            continue
        if k == "law" and isinstance(v, dict):
            continue
        t[k] = _inline(v)
    for k, v in value.items():
        if k == "law" and isinstance(v, dict):
            t[k] = _table(v)
        elif isinstance(v, list) and v and isinstance(v[0], dict) and k in _SUBTABLES:
            t[k] = _aot(v)
    return t


def _aot(items: list):
    import tomlkit

    out = tomlkit.aot()
    for item in items:
        out.append(_table(item))
    return out


def _encode_scene(linkage) -> dict:
    from ..model import RigidLink

    data = _encode_table(SPECS["scene"], linkage, "", typed=False)
    links = []
    for i, link in enumerate(linkage.links):
        spec = SPECS["links.rigid" if isinstance(link, RigidLink) else "links.soft"]
        entry = _encode_table(spec, link, f"links[{i}]", typed=True)
        extra = {}
        if linkage.parents[i] != i:
            extra["parent"] = int(linkage.parents[i])
        g = np.asarray(linkage.placements[i], dtype=float)
        if not np.array_equal(g, np.eye(4)):
            extra["placement"] = Pose().encode(g, f"links[{i}].placement")
        links.append({"type": entry.pop("type"), **extra, **entry})
    out = {k: v for k, v in data.items() if k not in ("contact",)}
    out["links"] = links
    for k in ("point_wrenches", "actuators", "closed_loops"):
        if k in out:
            out[k] = out.pop(k)
    if linkage.contact is not None:
        out["contact"] = _encode_contact(linkage.contact)
    return out


def _encode_contact(contact) -> dict:
    out = _encode_table(SPECS["contact"], contact, "contact", typed=False)
    obstacles = out.pop("obstacles", [])
    for k, lw in zip(contact.obstacle_law_index, contact.obstacle_laws, strict=True):
        obstacles[k]["law"] = _encode_table(
            SPECS["law"], lw, f"contact.obstacles[{k}].law", typed=False
        )
    shapes = []
    for link, shape in zip(contact.shape_links, contact.shapes, strict=True):
        entry = Table("shapes.sphere", "shapes.capsule", "shapes.box").encode(
            shape, "contact.shapes"
        )
        shapes.append({"type": entry.pop("type"), "link": int(link), **entry})
    law = out.pop("law")
    if shapes:
        out["shapes"] = shapes
    if contact.radius_links:
        out["radius"] = [
            {"link": int(k), "radius": float(r)}
            for k, r in zip(contact.radius_links, contact.radius, strict=True)
        ]
    if obstacles:
        out["obstacles"] = obstacles
    out["law"] = law
    return out


def _encode_settings(key: str, settings: dict) -> dict:
    spec = SPECS[key]
    known = {k.name: k for k in spec.keys}
    out = {}
    for name, value in settings.items():
        if name not in known:
            raise _Fail(
                f"{key}.{name}",
                f"is not a setting of [{key}]: give {', '.join(known)}.",
            )
        if value is None:
            continue
        kind = known[name].kind
        if isinstance(kind, Array):
            out[name] = np.asarray(value, dtype=float).reshape(-1).tolist()
        else:
            out[name] = kind.encode(value, f"{key}.{name}")
    return out


def save_linkage(
    path: str | os.PathLike,
    linkage,
    *,
    statics: dict | None = None,
    simulate: dict | None = None,
    description: str | None = None,
    overwrite: bool = False,
):
    """Write ``linkage`` (and optional default settings) to a TOML scene file.

    Loading the file with :func:`load_linkage` gives back an equal model (the same
    pytree structure and array values). Python functions in the model are written as
    ``"module:function"``: they must be module-level functions of an importable
    module (or ``equinox.Partial`` s of one with number and array arguments).

    Args:
        path: the file to write (``.toml``).
        linkage: the model.
        statics: optional settings of ``sorojax statics`` (``u``, ``q0``,
            ``load_steps``, ``max_steps``, ``rtol``, ``atol``, ...).
        simulate: optional settings of ``sorojax simulate`` (``t1``, ``u``,
            ``solver``, ``rtol``, ``atol``, ``n_save``, ...).
        description: one line saying what the scene is.
        overwrite: replace an existing file (default: refuse).

    Returns:
        The path written (a ``pathlib.Path``).

    Raises:
        FileExistsError: the file exists and ``overwrite`` is False (left unchanged).
        ValueError: something in the model cannot be saved (a lambda or closure as
            a hook, a size-class model), named.
    """
    p = as_path(path)
    text = dumps_scene(
        linkage, statics=statics, simulate=simulate, description=description
    )
    with writing(p, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return p


# ============================================================== key reference
def key_reference() -> str:
    """The key reference of the scene format (Markdown), generated from the schema."""
    _ensure_specs()
    out = []
    order = ["scene"] + [s for s in SPECS if s != "scene"]
    for name in order:
        spec = SPECS[name]
        out.append(f"### {name}\n")
        tag = f' (`type = "{spec.tag}"`)' if spec.tag else ""
        out.append(f"{spec.doc}{tag}\n")
        out.append("| key | value | default | meaning |")
        out.append("|---|---|---|---|")
        for k in spec.keys:
            default = "**required**" if k.default == REQUIRED else k.default
            cells = (k.kind.text, default, k.doc)
            text, default, doc = (c.replace("|", "\\|") for c in cells)
            out.append(f"| `{k.name}` | {text} | {default} | {doc} |")
        out.append("")
    return "\n".join(out)
