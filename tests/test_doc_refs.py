"""Every citation in the docs and in code comments resolves (issue #24 item 4).

A grep check (no C++ parser, no ctags) over docs/*.md, README.md and the
comments and docstrings of python/, cpp/, tests/, bench/ and examples/:

(a) repo paths (``python/sc_rt/hil/runner.py``, ``cpp/src/controllers.cpp``,
    short forms such as ``hil/floor.py`` or ``src/law_dsc.cpp``, bare file
    names such as ``twin.py``, globs, brace lists, markdown links) name files
    or directories that exist;
(b) symbols resolve: ``path:symbol`` and ``path::symbol`` are defined in that
    file; ``sc_rt.module.name`` and ``_core.Name`` in the package (and its
    stub); a C++ qualified name (``Class::member``, ``sc_rt::name``) in cpp/,
    as a member of the class body or an out-of-line definition; and a
    CamelCase name (``DscController``) or a backticked snake_case code name
    still occurs in the code (comments and docstrings do not count);
(c) the equation numbers the run fields of python/sc_rt/results/record/run.py (and
    RunMeta's, results/record/meta.py) cite
    are the numbers docs/MODEL.md gives the same quantity, read from
    MODEL.md's text.

What legitimately does not resolve (placeholders, outputs a run writes,
other projects' names) is in the allow-lists below, each with its reason;
an entry nothing needs any more fails the test. PENDING lists the drifts in
files this change could not edit, to be fixed there (it only shrinks).
"""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "python" / "sc_rt"
CPP = ROOT / "cpp"
MODEL = ROOT / "docs" / "MODEL.md"
RUN = PKG / "results" / "record" / "run.py"
META = PKG / "results" / "record" / "meta.py"  # RunMeta, whose attributes cite equations too

DOCS = [*sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md"]
CODE_DIRS = ("python", "cpp", "tests", "bench", "examples")
SELF = Path(__file__).resolve()  # its docstrings cite fakes on purpose
PY_EXT = (".py", ".pyi")
CPP_EXT = (".cpp", ".hpp", ".h")
# A name ending in one of these is a citation of a file.
SOURCE_EXT = ("py", "pyi", "cpp", "hpp", "h", "md", "toml", "lcm", "sh", "cmake")
# A path starting with one of these is checked even without an extension.
TOP_DIRS = ("python", "cpp", "docs", "tests", "bench", "examples", "scenarios", "tools", "lcmtypes", "cmake")
SKIP_DIRS = {".git", ".venv", "build", "__pycache__", ".pytest_cache", ".hypothesis", ".ruff_cache", "out"}

# --------------------------------------------------------------------------- #
# Allow-lists: citations that are legitimately not a file or name of this repo.

ALLOWED_PATHS = {
    "path/file.py": "placeholder of the plugin:path/file.py:Class syntax",
    "path/to/file.py": "placeholder of the file.py:Class law syntax",
    "file.py": "placeholder of the file.py:Class law syntax",
    "scenarios/x.toml": "placeholder scenario in an example error message",
    "my.toml": "the reader's own scenario in an example error message (docs/SCENARIOS.md, [laws.NAME])",
    "my_budget.toml": "the reader's own scenario in the gate's examples (--strict)",
    "slow_pd.toml": "the worked example with the paper's slow PD gains (docs/REQUIREMENTS.md section 3)",
    "my_law.cpp": "the reader's own plugin source in the plugin how-to",
    "my_pd.cpp": "the reader's own plugin source in the plugin how-to",
    "test_my_law.py": "the reader's own test in the plugin how-to",
    "claims.md": "written by `sc-rt reproduce`",
    "results.md": "bench/results.md, written by bench/run_all.py",
    "sc_rtConfig.cmake": "written by cmake at install, from cmake/sc_rtConfig.cmake.in",
    "sc_rt.cmake": "the exported-targets file cmake writes at install",
}
ALLOWED_PATH_PREFIXES = {
    "bench/results": "written by the benchmarks (gitignored)",
    "examples/quaternion_feedback/build": "the example's cmake build tree (gitignored)",
    "DIR/": "placeholder output directory in usage text",
    "sc_rt/lcmtypes": "the .lcm files cmake installs into the package (lcmtypes/CMakeLists.txt)",
    "sc_rt_lcm/": "headers generated from lcmtypes/*.lcm at build time",
    "src/fswAlgorithms/": "AVSLab/basilisk's paths: tests of issue #43 port its test cases and cite them",
    "src/simulation/": "AVSLab/basilisk's paths: tests of issue #43 port its test cases and cite them",
}
ALLOWED_PYREFS = {
    "sc_rt.pointing": "an MCAP schema name the export writes (docs/LOGS.md), not a Python name",
    "sc_rt.wheels": "an MCAP schema name the export writes (docs/LOGS.md), not a Python name",
    "sc_rt.law_telemetry": "an MCAP schema name the export writes (docs/LOGS.md), not a Python name",
    "sc_rt.lcm_raw_event": "an MCAP schema name the export writes (docs/LOGS.md), not a Python name",
}
# Names (CamelCase, snake_case in backticks) that are not identifiers of this repo's code.
ALLOWED_NAMES = {
    "RcvbufErrors": "a kernel UDP counter (/proc/net/snmp)",
    "sch_netem": "a kernel module",
    "JavaScript": "a language",
    "MyLaw": "the reader's own law class in the plugin how-to",
    "MyPd": "the reader's own law class in the plugin how-to",
}
# C++ namespaces that are not this repo's.
EXTERNAL_NAMESPACES = {"std", "Eigen", "py", "pybind11", "lcm"}

# --------------------------------------------------------------------------- #
# Reading the sources, fast (the whole check runs in about a second).


def _walk(top: Path):
    for p in sorted(top.rglob("*")):
        if p.is_file() and not SKIP_DIRS & set(p.relative_to(ROOT).parts):
            yield p


@functools.cache
def repo_files() -> tuple[Path, ...]:
    out = [p for p in ROOT.iterdir() if p.is_file()]
    for d in sorted(ROOT.iterdir()):
        if d.is_dir() and d.name not in SKIP_DIRS and not d.name.startswith("."):
            out.extend(_walk(d))
    return tuple(out)


@functools.cache
def basenames() -> frozenset[str]:
    return frozenset(p.name for p in repo_files())


@functools.cache
def read(path: Path) -> str:
    return path.read_text(encoding="utf-8", errors="replace")


def _line(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def _blank(s: str) -> str:
    return re.sub(r"[^\n]", " ", s)


_CPP_TOKENS = re.compile(
    r'R"(?P<d>[^(\s]*)\(.*?\)(?P=d)"|"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\''
    r"|(?P<c>//[^\n]*|/\*.*?\*/)", re.DOTALL)
_PY_TOKENS = re.compile(
    r'(?P<s>(?<![\w])[rRbBuUfF]{0,2}(?:"""(?:\\.|[^\\])*?"""|\'\'\'(?:\\.|[^\\])*?\'\'\''
    r'|"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\'))|(?P<c>#[^\n]*)', re.DOTALL)


@functools.cache
def lex(path: Path) -> tuple[tuple[tuple[int, str], ...], str]:
    """(comments and docstrings with their first line, the code without them).

    C++: // and /* */ comments. Python: # comments and docstrings (a string
    that starts a statement right after a ``:`` or at the top of the file)."""
    text = read(path)
    tokens = _CPP_TOKENS if path.suffix in CPP_EXT else _PY_TOKENS
    notes, code, last, tail = [], [], 0, ""  # tail: the last code character before a string
    for m in tokens.finditer(text):
        seg = text[last:m.start()].rstrip()
        tail = seg[-1] if seg else tail
        if m.group("c"):
            start, end = m.span("c")
        elif path.suffix in PY_EXT and m.group("s"):
            start, end = m.span("s")
            first_on_line = not text[text.rfind("\n", 0, start) + 1:start].strip()
            if not (first_on_line and tail in (":", "")):
                tail = '"'
                continue
        else:
            continue
        gap = text[last:start]
        if notes and m.group("c") and re.fullmatch(r"[ \t]*\n[ \t]*", gap) \
                and notes[-1][1].lstrip()[:1] in "#/":
            notes[-1] = (notes[-1][0], notes[-1][1] + "\n" + text[start:end])  # one comment over several lines
        else:
            notes.append((_line(text, start), text[start:end]))
        code += [gap, _blank(text[start:end])]
        last = end
    code.append(text[last:])
    return tuple(notes), "".join(code)


@functools.cache
def scanned_texts() -> tuple[tuple[str, int, str], ...]:
    """(file, first line, text) of every text the check reads."""
    out = [(str(p.relative_to(ROOT)), 1, read(p)) for p in DOCS]
    for d in CODE_DIRS:
        for p in _walk(ROOT / d):
            if p.suffix in PY_EXT + CPP_EXT and p.resolve() != SELF:
                out.extend((str(p.relative_to(ROOT)), ln, note) for ln, note in lex(p)[0])
    return tuple(out)


# --------------------------------------------------------------------------- #
# What exists: code identifiers, C++ definitions, Python module names.

_IDENT = re.compile(r"[A-Za-z_]\w*")


@functools.cache
def code_words() -> frozenset[str]:
    """Every identifier that occurs in code (comments and docstrings excluded)."""
    words: set[str] = set()
    for p in repo_files():
        if p.resolve() == SELF:
            continue
        if p.suffix in PY_EXT + CPP_EXT:
            words.update(_IDENT.findall(lex(p)[1]))
        elif p.suffix in (".lcm", ".toml", ".txt", ".cmake", ".in", ".sh") or p.name == "Makefile":
            comment = r"//[^\n]*|/\*.*?\*/" if p.suffix == ".lcm" else r"(?m)^\s*#[^\n]*"
            text = re.sub(comment, "", read(p), flags=re.DOTALL)
            words.update(_IDENT.findall(text))
    return frozenset(words)


@functools.cache
def cpp_code() -> dict[Path, str]:
    """Every C++ source of the repo with its comments blanked."""
    return {p: lex(p)[1] for p in repo_files() if p.suffix in CPP_EXT}


_TYPE_KW = r"\b(?:class|struct|union|namespace|enum(?:\s+class)?)\s+(?:\[\[[^\]]*\]\]\s*)?"


def _class_bodies(code: str, name: str):
    for m in re.finditer(_TYPE_KW + re.escape(name) + r"\b[^;{()]*\{", code):
        depth, i = 1, m.end()
        while depth and i < len(code):
            depth += {"{": 1, "}": -1}.get(code[i], 0)
            i += 1
        yield code[m.end():i]


@functools.cache
def cpp_member(cls: str, member: str, files: tuple[Path, ...] | None = None) -> bool | None:
    """Whether C++ type or namespace `cls` defines `member`; None if there is no such type."""
    member_def = re.compile(r"(?<![\w.>])~?" + re.escape(member) + r"\s*(?:\(|;|=|\{|\[|,|\}|:[^:])")
    out_of_line = re.compile(r"\b" + re.escape(cls) + r"\s*::\s*~?" + re.escape(member) + r"\s*\(")
    found = None
    for p in files or cpp_code():
        code = cpp_code()[p]
        if out_of_line.search(code):
            return True
        for body in _class_bodies(code, cls):
            found = False
            if member_def.search(body):
                return True
    return found


@functools.cache
def cpp_defines(name: str, files: tuple[Path, ...] | None = None) -> bool:
    """A C++ type, function, variable or macro `name` (declared or defined)."""
    n = re.escape(name)
    pat = re.compile(_TYPE_KW + n + r"\b|[\w>&*]\s+" + n + r"\s*(?:\(|=|;|\{|\[)|\busing\s+" + n
                     + r"\b|#define\s+" + n + r"\b")
    return any(pat.search(cpp_code()[p]) for p in files or cpp_code())


@functools.cache
def lcm_structs() -> frozenset[str]:
    # *.lcm.in: a type generated at build time from its template (controller_status_t)
    files = list((ROOT / "lcmtypes").glob("*.lcm")) + list((ROOT / "lcmtypes").glob("*.lcm.in"))
    return frozenset(re.findall(r"\bstruct\s+(\w+)", "".join(read(p) for p in files)))


class PyModule:
    """The top-level names of a Python module or stub, read with ast."""

    def __init__(self, path: Path):
        self.path = path
        parts = path.relative_to(PKG.parent).with_suffix("").parts if PKG in path.parents else (path.stem,)
        self.dotted = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        self.tree = ast.parse(read(path))
        self.names: dict[str, ast.AST] = {}
        self.imports: dict[str, tuple[str, int, str]] = {}  # name -> (module, level, attribute)
        for n in self.tree.body:
            self._collect(n)
        if "__getattr__" in self.names:  # a lazy module (sc_rt/__init__.py): its name tables
            for n in self.tree.body:
                if isinstance(n, (ast.Assign, ast.AnnAssign)) and isinstance(n.value, ast.Dict):
                    for k in n.value.keys:
                        if isinstance(k, ast.Constant) and isinstance(k.value, str):
                            self.names.setdefault(k.value, k)

    def _collect(self, n: ast.AST) -> None:
        if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            self.names[n.name] = n
        elif isinstance(n, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            for t in n.targets if isinstance(n, ast.Assign) else [n.target]:
                for e in ast.walk(t):
                    if isinstance(e, ast.Name):
                        self.names[e.id] = n
        elif isinstance(n, ast.Import):
            for a in n.names:
                self.names[(a.asname or a.name).split(".")[0]] = n
        elif isinstance(n, ast.ImportFrom):
            for a in n.names:
                self.names[a.asname or a.name] = n
                self.imports[a.asname or a.name] = (n.module or "", n.level, a.name)
        elif isinstance(n, (ast.If, ast.Try)):
            for b in ast.iter_child_nodes(n):
                self._collect(b)

    @staticmethod
    def class_attrs(node: ast.ClassDef) -> set[str]:
        out: set[str] = set()
        for n in ast.walk(node):
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                out.add(n.name)
            elif isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store):
                out.add(n.id)
            elif isinstance(n, ast.Attribute) and isinstance(n.ctx, ast.Store) \
                    and isinstance(n.value, ast.Name) and n.value.id == "self":
                out.add(n.attr)
        return out

    def defines(self, symbol: str) -> bool:
        first, *rest = symbol.split(".")
        node = self.names.get(first)
        if node is None:
            return False
        return not rest or not isinstance(node, ast.ClassDef) or rest[0] in self.class_attrs(node)


@functools.cache
def py_file(path: Path) -> PyModule:
    return PyModule(path.resolve())


@functools.cache
def py_module(dotted: str) -> PyModule | None:
    """sc_rt.a.b -> its module, package or stub (sc_rt._core)."""
    parts = dotted.split(".")
    if parts[0] != "sc_rt":
        return None
    base = PKG.joinpath(*parts[1:])
    for p in (base.parent / (base.name + ".py"), base.parent / (base.name + ".pyi"), base / "__init__.py"):
        if p.is_file():
            return py_file(p)
    return None


def py_resolve(dotted: str) -> str | None:
    """None when `sc_rt.x.y.z` resolves; else what is missing."""
    parts = dotted.split(".")
    cut = next((c for c in range(len(parts), 0, -1) if py_module(".".join(parts[:c]))), 0)
    if not cut:
        return f"no module {parts[0]}"
    mod, rest = py_module(".".join(parts[:cut])), parts[cut:]
    for _ in range(5):  # follow re-exports (from .x import y)
        if not rest:
            return None
        if rest[0] not in mod.names:
            return f"{mod.dotted} has no {rest[0]}"
        if rest[0] not in mod.imports:
            break
        src, level, attr = mod.imports[rest[0]]
        if level:
            pkg = mod.dotted.split(".")[: len(mod.dotted.split(".")) - level + (mod.path.name == "__init__.py")]
            src = ".".join(pkg + ([src] if src else []))
        if py_module(f"{src}.{attr}"):
            mod, rest = py_module(f"{src}.{attr}"), rest[1:]
        elif py_module(src):
            mod, rest = py_module(src), [attr, *rest[1:]]
        else:
            return None  # imported from elsewhere (numpy, ...)
    if len(rest) > 1 and not mod.defines(".".join(rest[:2])):
        return f"{mod.dotted}.{rest[0]} has no {rest[1]}"
    return None


@functools.cache
def py_class_files() -> dict[str, tuple[Path, ...]]:
    """The files of python/sc_rt (and the _core stub) that define each class name."""
    out: dict[str, list[Path]] = {}
    for p in repo_files():
        if p.suffix in PY_EXT and PKG in p.parents:
            for name in re.findall(r"(?m)^\s*class\s+(\w+)", lex(p)[1]):
                out.setdefault(name, []).append(p)
    return {k: tuple(v) for k, v in out.items()}


def py_class_has(cls: str, attr: str) -> bool | None:
    """Whether a Python class `cls` of the package has `attr`; None if there is no such class."""
    files = py_class_files().get(cls)
    if not files:
        return None
    for p in files:
        for n in ast.walk(py_file(p).tree):
            if isinstance(n, ast.ClassDef) and n.name == cls and attr in PyModule.class_attrs(n):
                return True
    return False


# --------------------------------------------------------------------------- #
# The checker.

_COMP = r"(?:[\w.*-]|\{[\w.,-]*\})+"
_PATH = re.compile(r"(?<![\w./:@$~*-])((?:\.\./)*" + _COMP + r"(?:/" + _COMP + r")+/?)")
_EXT = re.compile(r"\.(?:" + "|".join(SOURCE_EXT) + r")$")
_BARE = re.compile(r"(?<![\w./:@$~*-])([\w-]+\.(?:" + "|".join(SOURCE_EXT) + r"))(?![\w/*-])")
_AFTER = re.compile(r"(::?)([A-Za-z_][\w.]*|\d+)")
# `file.py: name_a, name_b` (code names only: with an underscore or called)
_NAMES_AFTER = re.compile(r":[ \t]+((?:[A-Za-z_]\w*(?:\(\))?)(?:,\s*(?:(?://|#)\s*)?[A-Za-z_]\w*(?:\(\))?)*)")
_LINK = re.compile(r"\]\(([^)\s]+)\)")
_PYREF = re.compile(r"(?<![\w./-])((?:sc_rt|_core)(?:\.[A-Za-z_]\w*)+)")
_QUALIFIED = re.compile(r"(?<![\w.:/-])([A-Za-z_]\w*)((?:::~?[A-Za-z_]\w*)+)")
_CLASSREF = re.compile(r"(?<![\w./])([A-Z]\w*[a-z]\w*)\.([a-z_]\w*)\b(?!\.\w|/)")
_CAMEL = re.compile(r"(?<![\w.$-])[A-Z][a-z0-9]+(?:[A-Z][a-z0-9]+)+\b")
_TICKED = re.compile(r"(?<!`)(`{1,2})([a-z_][a-z0-9_]*)(?:\(\))?\1(?!`)")


#: the allow-list entries that excused a citation (every entry must, see below)
ALLOWED_USED: set[str] = set()


def _allowed(key: str) -> bool:
    """Whether a citation that does not resolve is on an allow-list (and note the entry)."""
    hits = [a for a in (*ALLOWED_PATHS, *ALLOWED_PYREFS, *ALLOWED_NAMES) if key == a]
    hits += [a for a in ALLOWED_PATH_PREFIXES if key.startswith(a)]
    ALLOWED_USED.update(hits)
    return bool(hits)


def _expand(tok: str) -> list[str]:
    """`a/{b,c}.py` -> a/b.py, a/c.py; `x.hpp/.cpp` -> x.hpp, x.cpp."""
    m = re.search(r"\{([^{}]*)\}", tok)
    if m:
        return [e for alt in m.group(1).split(",") for e in _expand(tok[:m.start()] + alt + tok[m.end():])]
    m = re.match(r"(.*)\.(\w+)/\.(\w+)$", tok)
    if m:
        return [f"{m.group(1)}.{m.group(2)}", f"{m.group(1)}.{m.group(3)}"]
    return [tok]


def find_file(tok: str, where: Path) -> Path | bool | None:
    """The file a path citation names: the path, True for a directory or a glob that matches, None."""
    cands = [ROOT / tok, where.parent / tok]
    if tok.split("/")[0] not in TOP_DIRS:  # short forms: hil/floor.py, src/law_dsc.cpp, sc_rt/law.hpp
        cands += [PKG / tok, CPP / tok, CPP / "include" / tok, ROOT / "python" / tok, ROOT / "docs" / tok]
    for c in cands:
        if "*" in tok:
            if any(c.parent.glob(c.name)):
                return True
        elif c.is_file():
            return c
        elif c.is_dir():
            return True
    return None


def check_symbol(path: Path, symbol: str) -> bool:
    if symbol.isdigit():  # a line number
        return int(symbol) <= read(path).count("\n") + 1
    if path.suffix in PY_EXT:
        return py_file(path).defines(symbol)
    if path.suffix in CPP_EXT:
        first, *rest = re.split(r"::|\.", symbol)
        files = (path.resolve(),) if path.resolve() in cpp_code() else None
        return bool(cpp_member(first, rest[0], files)) if rest else cpp_defines(first, files)
    return True  # a section of a .md or .toml


def check_text(name: str, text: str, line0: int = 1) -> list[str]:
    """Every citation in one text (a doc, a comment or a docstring) that does not resolve."""
    where = ROOT / name
    problems: list[str] = []

    def bad(pos: int, what: str, key: str = "") -> None:
        if key and _allowed(key):
            return
        problems.append(f"{name}:{line0 + text.count(chr(10), 0, pos)}: {what}")

    # (a) paths, and (b) a symbol after a path
    for m in _PATH.finditer(text):
        whole = m.group(1).rstrip(".")
        after = _AFTER.match(text, m.start() + len(whole))
        for tok in _expand(whole):
            module = re.match(r"(.*/\w+)\.([A-Za-z_]\w*)$", tok)  # tests/refmath.RefController
            checked = _EXT.search(tok.rstrip("/")) or tok.split("/")[0] in TOP_DIRS + ("sc_rt",)
            if not (checked or module):
                continue  # prose (rad/s, and/or), a path of another tree or one a run writes
            found, symbol = find_file(tok, where), None
            if found is None and module and not _EXT.search(tok):
                found, symbol = find_file(module.group(1) + ".py", where), module.group(2)
            if found is None:
                if checked:
                    bad(m.start(), f"no such file: {tok}", tok)
                continue
            if after and symbol is None:
                symbol = after.group(2).rstrip(".")
            if symbol and isinstance(found, Path) and not check_symbol(found, symbol):
                bad(m.start(), f"{tok} defines no {symbol}")
            names = _NAMES_AFTER.match(text, m.start() + len(whole))
            if names and isinstance(found, Path) and found.suffix in PY_EXT + CPP_EXT:
                for n in re.findall(r"[A-Za-z_]\w*(?:\(\))?", names.group(1)):
                    if ("_" in n.strip("_") or n.endswith("()")) and not check_symbol(found, n.removesuffix("()")):
                        bad(m.start(), f"{tok} defines no {n}")
    for m in _BARE.finditer(text):
        after = _AFTER.match(text, m.end())  # controllers.cpp:symbol, in any file of that name
        if m.group(1) not in basenames():
            bad(m.start(), f"no file named {m.group(1)}", m.group(1))
        elif after and not any(check_symbol(p, after.group(2).rstrip(".")) for p in repo_files()
                               if p.name == m.group(1)):
            bad(m.start(), f"{m.group(1)} defines no {after.group(2)}")
    if name.endswith(".md"):
        for m in _LINK.finditer(text):
            target = m.group(1).split("#")[0]
            if target and not re.match(r"[a-z]+:", target) and not (where.parent / target).exists():
                bad(m.start(), f"broken link: {target}")
    # (b) Python names: sc_rt.x.y, _core.X, Class.attr
    for m in _PYREF.finditer(text):
        ref = m.group(1)
        why = py_resolve("sc_rt." + ref if ref.startswith("_core.") else ref)
        if why:
            bad(m.start(), f"{ref}: {why}", ref)
    for m in _CLASSREF.finditer(text):
        if py_class_has(*m.groups()) is False and not cpp_member(*m.groups()):
            bad(m.start(), f"{m.group(0)}: class {m.group(1)} has no {m.group(2)}")
    # (b) C++ qualified names
    for m in _QUALIFIED.finditer(text):
        ns, rest = m.group(1), m.group(2).split("::")[1:]
        if ns in EXTERNAL_NAMESPACES:
            continue
        if ns == "sc_rt_lcm":
            if rest[0] not in lcm_structs():
                bad(m.start(), f"{m.group(0)}: no LCM type {rest[0]}")
            continue
        if ns == "sc_rt":
            ns, rest = rest[0], rest[1:]
            if not rest:
                if not cpp_defines(ns):
                    bad(m.start(), f"{m.group(0)}: not defined in cpp/")
                continue
        has = cpp_member(ns, rest[0].lstrip("~"))
        if has is None:
            bad(m.start(), f"{m.group(0)}: no C++ class or namespace {ns}")
        elif not has:
            bad(m.start(), f"{m.group(0)}: {ns} has no member {rest[0]}")
    # (b) a CamelCase name anywhere, or a snake_case code name in backticks, still occurs in code
    names = {(m.start(), m.group(0)) for m in _CAMEL.finditer(text)}
    names |= {(m.start(), m.group(2)) for m in _TICKED.finditer(text)
              if re.fullmatch(r"[a-z][a-z0-9]+(?:_[a-z][a-z0-9]+)+", m.group(2).strip("_"))}
    for pos, ident in sorted(names):
        if ident not in code_words():
            bad(pos, f"{ident} occurs nowhere in the code", ident)
    return problems


@functools.cache
def all_problems() -> tuple[str, ...]:
    return tuple(p for name, line0, text in scanned_texts() for p in check_text(name, text, line0))


#: Drifts found in files this change could not edit (work in flight there),
#: as (file, what the check reports) -> the fix. Fix the comment, then delete
#: the entry: an entry the check no longer reports fails the test, so this
#: list only shrinks.
PENDING: dict = {}


def test_every_cited_path_and_symbol_resolves():
    reported = [(p, tuple(re.match(r"(.*?):\d+: (.*)", p).groups())) for p in all_problems()]
    problems = [p for p, key in reported if key not in PENDING]
    fixed = set(PENDING) - {key for _, key in reported}
    assert not problems, f"{len(problems)} citations do not resolve:\n" + "\n".join(problems)
    assert not fixed, "fixed, delete from PENDING: " + ", ".join(map(str, sorted(fixed)))


def test_every_allow_list_entry_is_still_needed():
    all_problems()
    stale = {*ALLOWED_PATHS, *ALLOWED_PATH_PREFIXES, *ALLOWED_PYREFS, *ALLOWED_NAMES} - ALLOWED_USED
    assert not stale, f"allow-list entries nothing needs any more: {sorted(stale)}"


def test_the_check_bites():
    fake = ("The law is in `cpp/src/nope.cpp` (`Foo::bar`), see python/sc_rt/bus/hil.py,\n"
            "`sc_rt.hil.runner.nope`, cpp/src/law_dsc.cpp:nope, controllers.cpp:law_step, `emulator.py`,\n"
            "`DscController::law_step` and [the model](NOPE.md).\n"
            "Fine: `cpp/src/law_dsc.cpp`, `Controller::step`, `sc_rt.hil.runner.run_hil`, hil/floor.py,\n"
            "tests/test_sim.py::test_python_and_cpp_engines_agree, [the model](MODEL.md).\n")
    fake_doc = "/".join(("docs", "INVENTED.md"))  # (not a literal: tests/test_selfcontained.py reads this file)
    problems = check_text(fake_doc, fake)
    text = "\n".join(problems)
    for cited in ("no such file: cpp/src/nope.cpp", "Foo::bar: no C++ class or namespace Foo",
                  "no such file: python/sc_rt/bus/hil.py", "sc_rt.hil.runner has no nope",
                  "cpp/src/law_dsc.cpp defines no nope", "controllers.cpp defines no law_step",
                  "no file named emulator.py", "DscController::law_step: no C++ class",
                  "DscController occurs nowhere", "broken link: NOPE.md"):
        assert cited in text, cited
    assert not [p for p in problems if p.startswith((f"{fake_doc}:4", f"{fake_doc}:5"))], text
    comment = "// the reference (sc_rt/model/plant.py: _inv3, rk4_step,\n// _nope_step), DscLaw::step\n"
    assert check_text("cpp/src/x.cpp", comment) == ["cpp/src/x.cpp:1: sc_rt/model/plant.py defines no _nope_step"]


# --------------------------------------------------------------------------- #
# (c) Equation numbers of the run fields against docs/MODEL.md.

#: The quantity of MODEL.md each run field that cites an equation holds, as
#: MODEL.md writes it (the left side of its defining equation, or the name it
#: gives the quantity). The numbers come from MODEL.md's text, not from here.
FIELD_SYMBOL = {
    "sigma_BD": "sigma_e",
    "omega_BD_B": "omega_e",
    "u_sat": "sat(uc_i)",
    "wheel_accel": "Omega_w_dot_i",
    "delta2": "delta_2",
    "H_N": "H",  # the total angular momentum of (3), in N
    "chi": "chi_i(t)",
    "lam": "lambda_i",
    "e1": "e1_i",
    "e2": "e2",
    "vs": "vs_dot",
    "fault_Y": "Y_i(t)",
    "ppc": "chi_i(t)",  # RunMeta.ppc: the envelope's parameters
}
#: Run fields whose doc has a number in parentheses that is not an equation.
NOT_EQUATIONS = {"P_diag": "(3) counts entries"}

_TAGS = r"((?:\(\d+\)\s*,?\s*)+)"


def _numbers(tags: str) -> set[int]:
    return {int(n) for n in re.findall(r"\((\d+)\)", tags)}


def model_numbers(text: str | None = None) -> dict[str, set[int]]:
    """symbol -> the equation numbers docs/MODEL.md attaches to it, from three forms:

    - a displayed (indented) equation ``S = ...    (N)``; one without a number
      takes the numbers of its lead-in paragraph when that starts with
      ``**Name** (N)`` or ends with ``(N):``;
    - an inline equation in backticks followed by its number: S on either
      side of its ``=``;
    - ``(N):`` and a sentence that names S in backticks (alone, or as the
      left side of an equation)."""
    text = read(MODEL) if text is None else text
    out: dict[str, set[int]] = {}

    def add(symbol: str, nums: set[int]) -> None:
        if nums and symbol.strip():
            out.setdefault(symbol.strip(), set()).update(nums)

    lead: set[int] = set()
    for para in re.split(r"\n[ \t]*\n", text):
        lines = para.split("\n")
        if all(ln.startswith("    ") for ln in lines if ln.strip()):  # a displayed block
            for ln in lines:
                m = re.match(r"\s*([^=<>]+?)\s*=[^=].*?" + _TAGS + r"(?:,\s*erratum \d+)?\s*$", ln)
                if m:
                    add(m.group(1), _numbers(m.group(2)))
                elif "=" in ln and not re.search(r"\(\d+\)", ln):
                    add(ln.split("=")[0], lead)
            continue
        lead = set()
        bold = re.match(r"\s*\*\*[^*]+\*\*\s*" + _TAGS, para)
        if bold:
            lead = _numbers(bold.group(1))
        elif re.search(_TAGS + r":\s*$", para):
            lead = _numbers(re.search(_TAGS + r":\s*$", para).group(1))
        for m in re.finditer(r"`([^`]+)`\s*" + _TAGS, para):
            sides = [s.strip() for s in m.group(1).split("=")]
            if len(sides) > 1:
                add(sides[0], _numbers(m.group(2)))
                add(sides[-1], _numbers(m.group(2)))
        for m in re.finditer(_TAGS + r":", para):
            sentence = re.split(r"\.\s", para[m.end():])[0]
            for t in re.findall(r"`([^`]+)`", sentence):
                add(t.split("=")[0] if "=" in t else t, _numbers(m.group(1)))
    return out


def run_field_citations() -> dict[str, set[int]]:
    """run field (or RunMeta attribute) -> the equation numbers its doc cites."""
    from sc_rt.results.record.run import FIELDS

    out = {f.name: _numbers(f.doc) for f in FIELDS}
    for m in re.finditer(r"#:([^\n]*)\n\s*(\w+)\s*:", read(RUN) + read(META)):
        out[m.group(2)] = _numbers(m.group(1))
    return {k: v for k, v in out.items() if v and k not in NOT_EQUATIONS}


def test_run_field_equation_numbers_match_model():
    model = model_numbers()
    cited = run_field_citations()
    problems = [f"run field {f} cites {sorted(n)} but has no entry in FIELD_SYMBOL" for f, n in cited.items()
                if f not in FIELD_SYMBOL]
    for field, symbol in FIELD_SYMBOL.items():
        if symbol not in model:
            problems.append(f"docs/MODEL.md gives {symbol} (run field {field}) no equation number")
        elif field not in cited:
            problems.append(f"FIELD_SYMBOL lists {field}, whose doc cites no equation")
        elif not cited[field] <= model[symbol]:
            problems.append(f"run field {field} cites {sorted(cited[field])}; docs/MODEL.md gives {symbol} "
                            f"{sorted(model[symbol])}")
    assert not problems, "\n".join(problems)


def test_model_numbers_reads_the_three_forms():
    text = ("**Rate error** (8): `omega_e = omega - w` (`omega_BD_B`).\n\n"
            "finally (20): a lumped `delta_2`. With `x3 = delta_2`\n(21):\n\n"
            "    A = 1\n    e2 = x2 - x2d      (27)\n    vs_dot = -k4 vs      (42), erratum 1\n")
    got = model_numbers(text)
    assert got["omega_e"] == {8} and got["delta_2"] == {20, 21} and got["A"] == {21}
    assert got["e2"] == {27} and got["vs_dot"] == {42}
