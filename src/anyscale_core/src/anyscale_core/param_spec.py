"""Parameters declared once (name, default, unit, bounds, one line of meaning); reading and
checking them through any `get(name, default)` with rospy.get_param's signature, and the
README's table rows, are built from that declaration. No ROS: tested without a master."""
from dataclasses import dataclass, field, fields
import math
from typing import Any, Callable, Dict, Iterable, List, Optional, Tuple

Getter = Callable[[str, Any], Any]


class ParamError(ValueError):
    """A parameter is missing or out of range; the message names it."""


REQUIRED = object()     # the default of a parameter that has none


@dataclass(frozen=True)
class Param:
    """One parameter. kind (by default the default's type): float, int, bool, str (non-empty),
    text (any string, also empty), name (non-empty, no spaces), frame (a tf frame id, kept
    without slashes), choice (one of `choices`), node_seconds (a dict node name -> s >= 0), raw
    (any value, for the caller to check)."""
    name: str
    default: Any
    doc: str
    unit: str = ""
    kind: str = ""
    minimum: Optional[float] = None
    maximum: Optional[float] = None
    above: bool = False                 # the minimum itself is refused
    finite: bool = True                 # false: +-inf is a value (a threshold that is off)
    choices: Tuple[str, ...] = ()

    def __post_init__(self):
        if not self.kind:
            object.__setattr__(self, "kind", _kind_of(self.default))
        if self.kind not in _CHECKS:
            raise ValueError(f"{self.name}: unknown parameter kind {self.kind!r}")
        if self.kind == "choice" and not self.choices:
            raise ValueError(f"{self.name}: a choice needs its choices")

    def read(self, get: Getter, prefix: str = "~") -> Any:
        """The checked value under prefix + name, or the default; ParamError names it."""
        full = prefix + self.name
        value = get(full, None if self.default is REQUIRED else self.default)
        if value is None and self.default is REQUIRED:
            raise ParamError(f"{full}: required, not set" + (f" ({self.doc})" if self.doc else ""))
        return self.check(value, full)

    def check(self, value: Any, full: Optional[str] = None) -> Any:
        return _CHECKS[self.kind](self, value, full or "~" + self.name)

    def expected(self) -> str:
        """What a valid value is, in words: 'a number >= 0.1', 'true or false'."""
        if self.kind in ("float", "int"):
            noun = "an integer" if self.kind == "int" else (
                "a number" if self.finite else "a number or inf")
            bounds = []
            if self.minimum is not None:
                bounds.append(f"{'>' if self.above else '>='} {self.minimum:g}")
            if self.maximum is not None:
                bounds.append(f"<= {self.maximum:g}")
            return " ".join([noun] + [" and ".join(bounds)] if bounds else [noun])
        return {"bool": "true or false", "str": "a non-empty string", "text": "a string",
                "name": "a name without spaces",
                "frame": "a tf frame name", "raw": "a value",
                "node_seconds": "a dict of node name: seconds >= 0",
                "choice": "one of " + ", ".join(self.choices)}[self.kind]

    def table_row(self, prefix: str = "~") -> str:
        """This parameter as a row of a README table: | name | default | unit | meaning |."""
        default = "required" if self.default is REQUIRED else _show(self.default)
        return f"| `{prefix}{self.name}` | {default} | {self.unit or '-'} | {self.doc} |"


def _show(value) -> str:
    if isinstance(value, bool):
        return "`true`" if value else "`false`"
    if isinstance(value, str):
        return f"`{value}`" if value else '`""`'
    if isinstance(value, float) and value == int(value) and abs(value) < 1e15:
        return f"`{value:g}`" if value != 0 else "`0`"
    return f"`{value!r}`" if not isinstance(value, dict) else f"`{value or '{}'}`"


def _refuse(p: Param, value, full: str):
    raise ParamError(f"{full}: expected {p.expected()}, got {value!r}")


def _number(p: Param, value, full: str):
    if isinstance(value, bool):
        _refuse(p, value, full)
    try:
        number = float(value)
    except (TypeError, ValueError):
        _refuse(p, value, full)
    if math.isnan(number) or (p.finite and math.isinf(number)):
        _refuse(p, value, full)
    if p.kind == "int":
        if number != int(number):
            _refuse(p, value, full)
        number = int(number)
    if p.minimum is not None and (number <= p.minimum if p.above else number < p.minimum):
        _refuse(p, value, full)
    if p.maximum is not None and number > p.maximum:
        _refuse(p, value, full)
    return number


def _bool(p: Param, value, full: str):
    if not isinstance(value, bool):     # the string "false" would be true
        _refuse(p, value, full)
    return value


def _string(p: Param, value, full: str):
    if not isinstance(value, str) or not value:
        _refuse(p, value, full)
    return value


def _text(p: Param, value, full: str):
    if not isinstance(value, str):
        _refuse(p, value, full)
    return value


def _name(p: Param, value, full: str):
    if not isinstance(value, str) or not value or any(c.isspace() for c in value):
        _refuse(p, value, full)
    return value


def _frame(p: Param, value, full: str):
    if not isinstance(value, str) or not value.strip("/") or any(c.isspace() for c in value):
        _refuse(p, value, full)
    return value.strip("/")            # tf2 frame ids carry no leading slash


def _choice(p: Param, value, full: str):
    if value not in p.choices:
        _refuse(p, value, full)
    return value


def _node_seconds(p: Param, value, full: str):
    if not isinstance(value, dict):
        _refuse(p, value, full)
    out = {}
    for node, seconds in value.items():
        if not isinstance(node, str) or isinstance(seconds, bool) \
                or not isinstance(seconds, (int, float)) \
                or not (math.isfinite(seconds) and seconds >= 0):
            raise ParamError(f"{full}: expected node name: seconds >= 0, got "
                             f"{node!r}: {seconds!r}")
        out[node] = float(seconds)
    return out


_CHECKS = {"float": _number, "int": _number, "bool": _bool, "str": _string, "text": _text,
           "name": _name, "frame": _frame, "choice": _choice, "node_seconds": _node_seconds,
           "raw": lambda p, value, full: value}


def read_all(params: Iterable[Param], get: Getter, prefix: str = "~") -> Dict[str, Any]:
    """Every parameter's checked value by name; the first bad one raises ParamError."""
    return {p.name: p.read(get, prefix) for p in params}


def declared(default, doc: str, unit: str = "", name: str = "", **bounds):
    """A dataclass field whose default is the parameter's, declared with it (the parameter is
    named like the field unless `name` says otherwise)."""
    if isinstance(default, dict):
        return field(default_factory=lambda: dict(default),
                     metadata={"param": (name, default, doc, unit, bounds)})
    return field(default=default, metadata={"param": (name, default, doc, unit, bounds)})


def _declared_fields(cls) -> List[Tuple[str, Param]]:
    out = []
    for f in fields(cls):
        if "param" not in f.metadata:
            continue
        name, default, doc, unit, bounds = f.metadata["param"]
        out.append((f.name, Param(name or f.name, default, doc, unit, **bounds)))
    return out


def dataclass_params(cls) -> List[Param]:
    """The Params of a dataclass's `declared` fields, in field order."""
    return [p for _, p in _declared_fields(cls)]


def read_dataclass(cls, get: Getter, prefix: str = "~", **given):
    """An instance of `cls` with each declared field read as its parameter; `given` fills
    the fields that are not parameters (or overrides one)."""
    kwargs = dict(given)
    for field_name, p in _declared_fields(cls):
        if field_name not in kwargs:
            kwargs[field_name] = p.read(get, prefix)
    return cls(**kwargs)


def _kind_of(default) -> str:
    if default is REQUIRED:
        return "str"
    if isinstance(default, bool):
        return "bool"
    if isinstance(default, int):
        return "int"
    if isinstance(default, float):
        return "float"
    if isinstance(default, dict):
        return "node_seconds"
    return "str"
