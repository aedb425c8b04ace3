"""A run's output directory: one writer for every command that ends a run
(``sc-rt sim``, ``sc-rt hil``, ``sc-rt report``, the demo)."""

from __future__ import annotations

from pathlib import Path

from sc_rt.results.record.jsonsafe import atomic_path
from sc_rt.results.record.run import Run, write_json

__all__ = ["write_run", "check_out_dir", "OutDir", "OutDirInUse", "MANIFEST"]


def check_out_dir(out: Path, option: str = "--out") -> str | None:
    """Why ``out`` cannot be a run's output directory (None: it can).
    Checked before a run starts, so that nothing runs for nothing."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        return f"{option} {out}: exists and is not a directory"
    probe = out
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        return f"{option} {out}: {probe} is not a directory"
    import os

    if not os.access(probe, os.W_OK | os.X_OK):
        return f"{option} {out}: {probe} is not writable"
    return None


#: Rows a figure draws at most (a longer run is decimated: Run.decimated)
FIGURE_ROWS = 40_000


def write_run(run: Run, out: Path, *, figures: bool = True, title: str = "") -> list[Path]:
    """trajectory.arrow (the one on-disk format of a run, whatever produced
    it: ``Run.save_arrow``), metrics.json, timing.json (bench runs) and the
    figures into ``out``; returns every file written, in order.

    Parameters
    ----------
    run : Run
        The run record (``sc_rt.simulate``, ``sc_rt.run_hil``, a log's rebuild).
    out : Path
        The output directory, created with its parents when missing; files
        of the same names in it are replaced.
    figures : bool
        Also write the tracking figures, the wheel speed figure and the
        requirements' figure (and, with ``run.timing``, the timing figures).
    title : str
        The second title line of the tracking figures ("": "scenario, law,
        engine" of ``run.meta``).

    Returns
    -------
    list of Path
        Every file written, in order: trajectory.arrow, metrics.json,
        timing.json (when ``run.timing`` is set), then the figures.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if (run_id := claimed_run_id(out)) is not None:  # the run that holds the directory (OutDir)
        run.metrics["run_id"] = run_id
    every = int(getattr(run.meta, "record_every", 1))
    if figures:  # from every row, before the saved rows are thinned ([record] every)
        paths_fig = _figures(run, out, title)
    saved = run.thinned(every)
    traj = saved.save_arrow(out / "trajectory.arrow")
    # what the run was made from (RunMeta.inputs: the scenario file and its sha256, overrides, the law's
    # parameters as run, sc-rt's version and commit), beside its verdict: a gate's file traces to its inputs
    inputs = getattr(run.meta, "inputs", None)
    paths = [traj, write_json(out / "metrics.json", {**run.metrics, **({"inputs": inputs} if inputs else {})})]
    if run.timing is not None:
        paths.append(write_json(out / "timing.json", run.timing))
    if figures:
        paths += paths_fig
    return paths


def _figures(run: Run, out: Path, title: str) -> list[Path]:
    """The tracking, wheel speed, requirements, (magnetic control) momentum and
    dipole, and (bench runs) timing figures."""
    from sc_rt.results.present import figures as fig
    from sc_rt.results.present.calibration_figure import calibration_figure
    from sc_rt.results.present.magnetic_figure import magnetic_figure
    from sc_rt.results.present.telemetry_figure import telemetry_figure
    from sc_rt.results.present.requirement_figures import requirement_figures

    drawn = run.decimated(FIGURE_ROWS) if run.is_stored else run  # a run on disk: peaks kept
    paths = fig.tracking_figures(drawn, out, title=title)
    paths += requirement_figures(drawn, out, title=title)  # wheel_speeds.png, requirements.png
    if (p := telemetry_figure(drawn, out, title)) is not None:  # the law's own telemetry, when it has any
        paths.append(p)
    if (p := calibration_figure(drawn, out, title)) is not None:  # a calibrating filter's estimates
        paths.append(p)
    if (p := magnetic_figure(drawn, out, title)) is not None:  # magnetic control: momentum and dipoles
        paths.append(p)
    if run.timing is not None:
        paths += fig.timing_figures(drawn, out)
    return paths


#: A run's claim on its output directory while it lasts (the pid of the process)
LOCK = ".sc-rt.lock"
#: What the run that last used the directory wrote (its run id, and the files
#: that were there before it, which are not its own)
MANIFEST = ".sc-rt-run.json"


class OutDirInUse(Exception):
    """The output directory is claimed by a live run (one line, for exit 2)."""


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() or p.is_symlink()} - {LOCK, MANIFEST}


def _alive(pid: int) -> bool:
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class OutDir:
    """A run's output directory, owned by the run while it lasts: outputs
    belong to their run (docs/HIL.md, "When a run is valid").

    ``claim()`` refuses a directory that a live run holds (a lock file with
    its pid: two runs into one ``--out`` at once), removes what the previous
    run there wrote (its manifest lists it: a rerun with ``--no-plots`` keeps
    no figure of the run before), and records the files already there that
    are not a run's (yours: left alone, never embedded in a report). The run
    id stamped in metrics.json (``run_id``) and the manifest tie the outputs
    to their run; ``release()`` writes the manifest and drops the lock."""

    def __init__(self, path: Path, option: str = "--out"):
        import uuid

        self.path, self.option = Path(path), option
        self.run_id = uuid.uuid4().hex
        self.foreign: set[str] = set()
        self._claimed = False

    def claim(self, keep_previous: bool = False) -> OutDir:
        """Take the directory (module docstring). ``keep_previous``: the
        previous run's outputs stay and become this run's (a campaign that
        resumes its own dataset)."""
        import json
        import os

        self.path.mkdir(parents=True, exist_ok=True)
        lock = self.path / LOCK
        for _attempt in range(2):
            try:
                fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                try:
                    pid = int(lock.read_text().split()[0])
                except (OSError, ValueError, IndexError):
                    pid = -1
                if pid > 0 and pid != os.getpid() and _alive(pid):
                    raise OutDirInUse(f"{self.option} {self.path}: in use by a live run (pid {pid}, "
                                      f"{lock}); give another directory") from None
                lock.unlink(missing_ok=True)  # a run that died without releasing it
                continue
            with os.fdopen(fd, "w") as f:
                f.write(f"{os.getpid()} {self.run_id}\n")
            break
        else:
            raise OutDirInUse(f"{self.option} {self.path}: cannot take its lock {lock}")
        self._claimed = True
        man = self.path / MANIFEST
        previous: dict = {}
        try:
            previous = json.loads(man.read_text())
        except (OSError, ValueError):
            pass
        own = set(previous.get("files", []))
        if previous and not previous.get("done"):  # it died before its release: all it added
            own |= _files(self.path) - set(previous.get("foreign", []))
        if keep_previous:  # what the previous run wrote is this run's too
            self.foreign = _files(self.path) - own
            self._write_manifest(done=False)
            return self
        for rel in sorted(own):  # the previous run's own outputs, and nothing else
            if ".." not in Path(rel).parts:
                (self.path / rel).unlink(missing_ok=True)
        self.foreign = _files(self.path)
        self._write_manifest(done=False)
        return self

    def _write_manifest(self, done: bool) -> None:
        import json

        own = sorted(_files(self.path) - self.foreign)
        with atomic_path(self.path / MANIFEST) as tmp:
            tmp.write_text(json.dumps({"run_id": self.run_id, "done": done, "files": own,
                                       "foreign": sorted(self.foreign)}, indent=1) + "\n")

    def release(self) -> None:
        if not self._claimed:
            return
        self._claimed = False
        try:
            self._write_manifest(done=True)
        except OSError:  # a full disk: the next run treats this one as died (all it added is its own)
            pass
        finally:
            (self.path / LOCK).unlink(missing_ok=True)


def claimed_run_id(out: Path) -> str | None:
    """The id of the run that holds ``out`` now (its lock), None when none does."""
    try:
        parts = (Path(out) / LOCK).read_text().split()
    except OSError:
        return None
    return parts[1] if len(parts) > 1 else None


def run_files(run_dir: Path) -> set[str] | None:
    """The files of the run that wrote ``run_dir`` (relative paths), from its
    manifest: everything there but what was there before it. None without a
    manifest (a directory sc-rt did not claim: every file counts)."""
    import json

    run_dir = Path(run_dir)
    try:
        foreign = set(json.loads((run_dir / MANIFEST).read_text()).get("foreign", []))
    except (OSError, ValueError):
        return None
    return _files(run_dir) - foreign
