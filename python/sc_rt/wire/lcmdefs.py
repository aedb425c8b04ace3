"""The ``.lcm`` type definitions as data, and JSON schemas generated from them.

``parse_lcm`` reads the struct definitions (package, fields with their
types and dimensions, constants, the comments above each field) of the
files that ``wire.lcm_sources()`` finds; ``json_schema`` turns one struct
into the JSON schema of its JSON encoding (``sc-rt export``'s MCAP
channels). A field added to a ``.lcm`` file appears in the schema with no
edit here.

JSON encoding of a message (what the schema describes):

- integers (``int8_t`` .. ``int64_t``, ``byte``) are JSON integers;
- ``float``/``double`` are JSON numbers; a value that is not finite (NaN,
  inf: JSON has none) is ``null``;
- ``boolean`` is ``true``/``false``; ``string`` a JSON string;
- an array ``T x[3][4]`` nests JSON arrays (3 of 4); a variable
  dimension (a field name) is an array of that field's length;
- a field whose type is another struct of the same files is that struct's
  object.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["LcmField", "LcmStruct", "parse_lcm", "load_definitions", "json_schema", "PRIMITIVES"]

#: LCM primitive -> (JSON schema of one value)
PRIMITIVES: dict[str, dict] = {
    "int8_t": {"type": "integer", "minimum": -(2 ** 7), "maximum": 2 ** 7 - 1},
    "int16_t": {"type": "integer", "minimum": -(2 ** 15), "maximum": 2 ** 15 - 1},
    "int32_t": {"type": "integer", "minimum": -(2 ** 31), "maximum": 2 ** 31 - 1},
    "int64_t": {"type": "integer", "minimum": -(2 ** 63), "maximum": 2 ** 63 - 1},
    "byte": {"type": "integer", "minimum": 0, "maximum": 255},
    "float": {"type": "number"},
    "double": {"type": "number"},
    "boolean": {"type": "boolean"},
    "string": {"type": "string"},
}


@dataclass(frozen=True)
class LcmField:
    name: str
    type: str
    dims: tuple[int | str, ...]  # int: fixed length; str: the field holding the length
    comment: str = ""


@dataclass
class LcmStruct:
    package: str
    name: str
    fields: list[LcmField]
    constants: dict[str, tuple[str, str]] = field(default_factory=dict)  # name -> (type, value)
    comment: str = ""
    source: str = ""

    @property
    def full_name(self) -> str:
        return f"{self.package}.{self.name}" if self.package else self.name


_BLOCK = re.compile(r"/\*(.*?)\*/", re.S)
_IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
_FIELD = re.compile(rf"^({_IDENT}(?:\.{_IDENT})?)\s+(.+)$")
_NAME_DIMS = re.compile(rf"^({_IDENT})\s*((?:\[\s*[A-Za-z0-9_]+\s*\]\s*)*)$")


def _strip_comments(text: str) -> list[tuple[str, str]]:
    """(code, comment) per line; a block comment becomes comment lines."""
    text = _BLOCK.sub(lambda m: "\n".join("//" + ln.strip(" *") for ln in m.group(1).split("\n")), text)
    out = []
    for line in text.split("\n"):
        code, _, comment = line.partition("//")
        out.append((code.strip(), comment.strip()))
    return out


def parse_lcm(text: str, source: str = "") -> list[LcmStruct]:
    """The structs of one ``.lcm`` file. Raises ValueError naming the line
    for anything it does not understand."""
    package = ""
    structs: list[LcmStruct] = []
    cur: LcmStruct | None = None
    pending: list[str] = []
    # statements can span lines: accumulate code up to ';', '{' or '}'
    buf, buf_line, buf_comment = "", 0, ""
    for lineno, (code, comment) in enumerate(_strip_comments(text), 1):
        if comment and not code:
            pending.append(comment)
            continue
        for ch in code:
            if not buf.strip():
                buf_line, buf_comment = lineno, " ".join(pending)
            if ch in ";{}":
                stmt = buf.strip()
                buf = ""
                where = f"{source}:{buf_line}"
                if ch == "{":
                    m = re.fullmatch(rf"struct\s+({_IDENT})", stmt)
                    if not m or cur is not None:
                        raise ValueError(f"{where}: cannot parse {stmt!r} {{")
                    cur = LcmStruct(package, m.group(1), [], comment=buf_comment, source=source)
                elif ch == "}":
                    if stmt or cur is None:
                        raise ValueError(f"{where}: unexpected '}}'")
                    structs.append(cur)
                    cur = None
                else:
                    package = _statement(stmt, cur, where, buf_comment, package)
                pending = []
            else:
                buf += ch
        buf += " "
    if buf.strip() or cur is not None:
        raise ValueError(f"{source}: unterminated definition at the end")
    return structs


def _statement(stmt: str, cur: LcmStruct | None, where: str, comment: str, package: str) -> str:
    """Add one statement (field, constant) to ``cur``; returns the package."""
    if not stmt:
        return package
    if stmt.startswith("package "):
        return stmt.split(None, 1)[1].strip()
    if cur is None:
        raise ValueError(f"{where}: {stmt!r} outside a struct")
    if stmt.startswith("const "):
        m = re.fullmatch(rf"const\s+({_IDENT})\s+(.+)", stmt, re.S)
        if not m:
            raise ValueError(f"{where}: cannot parse constant {stmt!r}")
        for part in m.group(2).split(","):
            name, eq, value = part.partition("=")
            if not eq:
                raise ValueError(f"{where}: constant without a value in {stmt!r}")
            cur.constants[name.strip()] = (m.group(1), value.strip())
        return package
    m = _FIELD.match(stmt)
    if not m:
        raise ValueError(f"{where}: cannot parse field {stmt!r}")
    tname = m.group(1)
    for part in m.group(2).split(","):
        nm = _NAME_DIMS.match(part.strip())
        if not nm:
            raise ValueError(f"{where}: cannot parse field {part.strip()!r}")
        dims = tuple(int(d) if d.isdigit() else d for d in re.findall(r"\[\s*([A-Za-z0-9_]+)\s*\]", nm.group(2)))
        cur.fields.append(LcmField(nm.group(1), tname, dims, comment))
    return package


def load_definitions(files: list[Path] | None = None) -> dict[str, LcmStruct]:
    """Every struct of ``files`` (default ``wire.lcm_sources()``), by its
    short name (``plant_state_t``)."""
    if files is None:
        from sc_rt.wire.codec import lcm_sources

        files = lcm_sources()
    out: dict[str, LcmStruct] = {}
    for f in files:
        for s in parse_lcm(Path(f).read_text(), Path(f).name):
            out[s.name] = s
    return out


def _value_schema(tname: str, defs: dict[str, LcmStruct], seen: tuple[str, ...]) -> dict:
    if tname in PRIMITIVES:
        return dict(PRIMITIVES[tname])
    short = tname.rsplit(".", 1)[-1]
    if short in defs and short not in seen:
        return _object_schema(defs[short], defs, seen + (short,))
    raise ValueError(f"type {tname!r} is neither an LCM primitive nor a struct of the .lcm files")


def _object_schema(s: LcmStruct, defs: dict[str, LcmStruct], seen: tuple[str, ...]) -> dict:
    props = {}
    for f in s.fields:
        sch = _value_schema(f.type, defs, seen)
        for d in reversed(f.dims):
            arr: dict = {"type": "array", "items": sch}
            if isinstance(d, int):
                arr["minItems"] = arr["maxItems"] = d
            sch = arr
        desc = f.comment
        if f.type in ("float", "double"):
            desc = (desc + " " if desc else "") + "(null: not finite)"
        if desc:
            sch = {**sch, "description": desc}
        props[f.name] = sch
    return {"title": s.full_name, "type": "object", "properties": props,
            "required": [f.name for f in s.fields], "additionalProperties": False}


def json_schema(s: LcmStruct, defs: dict[str, LcmStruct] | None = None) -> dict:
    """The JSON schema of the JSON encoding of struct ``s``."""
    defs = defs or {s.name: s}
    out = _object_schema(s, defs, (s.name,))
    desc = s.comment
    if s.constants:
        consts = ", ".join(f"{k} = {v}" for k, (_t, v) in s.constants.items())
        desc = (desc + " " if desc else "") + f"Constants: {consts}."
    if desc:
        out["description"] = desc
    return out
