"""The law of a run, resolved once where the run is planned (issue 38 item 2).

A law spec (a string of the scenario's ``[controller] law``, ``--law``, or a
class) becomes one typed reference, a tagged union on ``kind``:

- :class:`BuiltinLaw`: a law of the core's registry (``dsc-ppc``, ``pd``, ...);
- :class:`PluginLaw`: a C++ plugin, with its library file and that file's SHA-256;
- :class:`PythonLaw`: a Python class, with its module or file (and the file's SHA-256);
- :class:`ExternalLaw`: a controller the bench does not start or one it starts
  by a command (``sc-rt hil --external``), named by what it says.

Resolving loads the law (a plugin's library, a Python law's module: law
code runs here, never in ``sc_rt.scenario.reader.load_scenario``) and probes
it once at rest at t = 0 with the scenario's table, in a forked child killed
after ``sc_rt.isolate.probe_timeout()`` seconds: its problems are the
scenario's errors (ScenarioError, exit 2 at the command line) on the law's
key or on the parameter's own key.
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Union

from sc_rt import _core
from sc_rt.isolate import PROBE_TIMEOUT_ENV, ChildDied, ChildTimedOut, call_in_child, probe_timeout
from sc_rt.pylaw import PYTHON_PREFIX, is_python_law, law_label, load_law
from sc_rt.scenario.tables.laws import report_issues
from sc_rt.scenario.model import LAWS, PLUGIN_PREFIX, Scenario
from sc_rt.scenario.schema import Doc, ScenarioError, key_lines

__all__ = ["BuiltinLaw", "PluginLaw", "PythonLaw", "ExternalLaw", "LawRef", "law_ref", "probe_law",
           "resolve_law", "law_from_dict"]


@dataclass(frozen=True)
class BuiltinLaw:
    """A law of the core's registry, by its name."""

    name: str
    kind: Literal["builtin"] = "builtin"

    @property
    def spec(self) -> str:
        return self.name


@dataclass(frozen=True)
class PluginLaw:
    """A C++ law plugin: its spec (``plugin:PATH_OR_NAME``), declared name,
    library file and the file's SHA-256 (hex; None when it cannot be read)."""

    spec: str
    name: str
    path: str
    sha256: str | None
    kind: Literal["plugin"] = "plugin"


@dataclass(frozen=True)
class PythonLaw:
    """A Python law (sc_rt.pylaw): its spec (``python:module:Class`` or
    ``python:/abs/file.py:Class``), its ``name`` (labels the run, names its
    table), the module or file, and the file's SHA-256 (None for a module)."""

    spec: str
    name: str
    module: str
    sha256: str | None
    kind: Literal["python"] = "python"


@dataclass(frozen=True)
class ExternalLaw:
    """A controller process the bench does not own (hil/external.py): one it
    starts by a command line (``command``, ``sc-rt hil --external``; with
    the placeholders ``{url}`` ...) or, ``command`` None, one started by hand
    that the bench waits for (``--external-wait``). Its law is its own; the
    configuration it is given is the scenario's."""

    command: str | None = None
    name: str = "external"
    kind: Literal["external"] = "external"

    @property
    def spec(self) -> str:
        return self.name


LawRef = Union[BuiltinLaw, PluginLaw, PythonLaw, ExternalLaw]
_KINDS = {"builtin": BuiltinLaw, "plugin": PluginLaw, "python": PythonLaw, "external": ExternalLaw}


def _sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def law_ref(spec: str) -> LawRef:
    """The typed reference of a law spec, its library or class loaded (law
    code runs: a Python law's module is imported). ValueError with a
    one-line reason when it does not load."""
    if is_python_law(spec):
        spec = spec if spec.startswith(PYTHON_PREFIX) else PYTHON_PREFIX + spec
        cls = load_law(spec)
        target = spec[len(PYTHON_PREFIX):].rpartition(":")[0]
        src = Path(target)
        is_file = src.suffix == ".py" and src.is_file()
        return PythonLaw(spec=spec, name=law_label(cls), module=target, sha256=_sha256(src) if is_file else None)
    if spec.startswith(PLUGIN_PREFIX):
        info = _core.law_info(spec)  # loads the library
        return PluginLaw(spec=spec, name=info["name"], path=str(info["source"]), sha256=_sha256(Path(info["source"])))
    return BuiltinLaw(name=spec)


def law_from_dict(d: dict[str, Any]) -> LawRef:
    """A reference from its recorded form (``dataclasses.asdict``), not loaded."""
    d = dict(d)
    return _KINDS[d.pop("kind")](**d)


def _doc(scn: Scenario, overridden: bool) -> Doc:
    """The scenario file's Doc for the probe's errors (its lines when it reads)."""
    if overridden:
        return Doc(f"{scn.path} (override)", {})
    try:
        return Doc(str(scn.path), key_lines(Path(scn.path).read_text(encoding="utf-8")))
    except (OSError, UnicodeDecodeError):
        return Doc(str(scn.path), {})


def probe_law(scn: Scenario, overridden: bool = False, probe_python: bool = True) -> LawRef:
    """The scenario's law (``scn.run.controller``) loaded and constructed once
    with its table, probed one step at rest at t = 0 in a child process
    (killed after sc_rt.isolate.probe_timeout() s). ``overridden``: the law
    came from the command line (its errors name ``<file> (override)``);
    ``probe_python`` False: a Python law is loaded, not probed (the bench
    runs a Python law it is given in ``sc-rt controller``, which constructs
    and checks it itself: its reset may wait for the run to start). Raises
    ScenarioError naming the law's key or the parameter's own key."""
    doc = _doc(scn, overridden)
    spec = scn.run.controller
    law_key = "run.controller" if overridden else scn.law_key
    if spec in LAWS:
        return BuiltinLaw(name=spec)  # its table was checked as the file was read
    try:
        ref = law_ref(spec)
    except ValueError as e:
        doc.error(law_key, spec, str(e) if overridden else str(e).replace("--law ", "law ", 1))
        raise ScenarioError(doc.path, doc.errors) from None
    if isinstance(ref, BuiltinLaw) or (isinstance(ref, PythonLaw) and not probe_python):
        return ref  # (a BuiltinLaw here: a name of a loaded plugin's registry, as the file gave it)
    table = scn.controller.table(ref.name) or scn.controller.table(spec)
    try:
        timeout = probe_timeout()
    except ValueError as e:
        doc.error(law_key, spec, f"the law's probe: {e}")
        raise ScenarioError(doc.path, doc.errors) from None
    try:
        cfg = scn.core_config(law=spec)
        try:  # native code: a crash in the probe is a refusal, and so is a law that does not return
            issues = call_in_child(_core.check_law, cfg, timeout=timeout)
        except ChildTimedOut:
            issues = [("law", f"law {spec}: did not return within {timeout:g} s when constructed and "
                              f"probed at rest at t = 0 (killed; {PROBE_TIMEOUT_ENV} sets the limit)")]
        except ChildDied as e:
            issues = [("law", f"law {spec}: crashed the process when probed at rest at t = 0 ({e.how})")]
    except ValueError as e:  # the config itself (LCM translation)
        issues = [("law", str(e))]
    where = {(ref.name if law == spec else law, k): v for (law, k), v in scn.law_keys}
    report_issues(doc, issues, spec, ref.name, table, law_key, where, set())
    if doc.errors:
        raise ScenarioError(doc.path, doc.errors)
    return ref


def resolve_law(scn: Scenario, overridden: bool = False, probe_python: bool = True) -> tuple[Scenario, LawRef]:
    """(the scenario with its law's spec as resolved, the law's reference):
    :func:`probe_law`, once per run, where the run is planned."""
    ref = probe_law(scn, overridden, probe_python)
    if isinstance(ref, PythonLaw) and ref.spec != scn.run.controller:
        scn = dataclasses.replace(scn, run=dataclasses.replace(scn.run, controller=ref.spec))
    return _named_table(scn, scn.run.controller, ref), ref


def _named_table(scn: Scenario, spec: str, ref: LawRef) -> Scenario:
    """``[controller.params]`` of a plugin or Python law, kept under its spec
    by the reader (which loads no law), named by the law's own name now that
    it is known (``scn.controller.table(ref.name)``). ScenarioError when the
    file gives that law's table twice ([laws.NAME] and [controller.params])."""
    name = getattr(ref, "name", spec)
    laws = scn.controller.laws
    if name == spec or not any(law == spec for law, _ in laws):
        return scn
    if any(law == name and items for law, items in laws):
        doc = _doc(scn, False)
        doc.error("controller.params", None, f"give the parameters of {name} once: [laws.{name}] or "
                                             "[controller.params], not both")
        raise ScenarioError(doc.path, doc.errors)
    tables = tuple((name if law == spec else law, items) for law, items in laws if not (law == name and not items))
    keys = tuple(((name if law == spec else law, k), v) for (law, k), v in scn.law_keys)
    return dataclasses.replace(scn, controller=dataclasses.replace(scn.controller, laws=tables), law_keys=keys)
