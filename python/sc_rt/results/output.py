"""A run's output directory: one writer for every command that ends a run
(``sc-rt sim``, ``sc-rt hil``, ``sc-rt report``, the demo)."""

from __future__ import annotations

from pathlib import Path

from sc_rt.results.run import Run, write_json

__all__ = ["write_run", "check_out_dir"]


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


def write_run(run: Run, out: Path, *, figures: bool = True, title: str = "",
              compress: bool = True) -> list[Path]:
    """trajectory.npz, metrics.json, timing.json (bench runs) and the
    figures into ``out``; returns every file written, in order.

    Parameters
    ----------
    run : Run
        The run record (``sc_rt.simulate``, ``sc_rt.run_hil``, a log's rebuild).
    out : Path
        The output directory, created with its parents when missing; files
        of the same names in it are replaced.
    figures : bool
        Also write the tracking figures (and, with ``run.timing``, the
        timing figures).
    title : str
        The second title line of the tracking figures ("": "scenario, law,
        engine" of ``run.meta``).
    compress : bool
        Write trajectory.npz compressed (``numpy.savez_compressed``).

    Returns
    -------
    list of Path
        Every file written, in order: trajectory.npz, metrics.json,
        timing.json (when ``run.timing`` is set), then the figures.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [run.save_npz(out / "trajectory.npz", compress=compress),
             write_json(out / "metrics.json", run.metrics)]
    if run.timing is not None:
        paths.append(write_json(out / "timing.json", run.timing))
    if figures:
        from sc_rt.results import figures as fig

        paths += fig.tracking_figures(run, out, title=title)
        if run.timing is not None:
            paths += fig.timing_figures(run, out)
    return paths
