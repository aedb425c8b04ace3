"""Scenario files refused in bounded time and memory (issue 40, item 8;
docs/SCENARIOS.md "Errors"): /dev/zero, a FIFO, a directory, a symlink
loop, a file over the 1 MiB limit, arrays or dotted keys nested deeper than
32 levels; each one line naming the file (and the line), exit 2, nothing
started; a reference file the same. The commands run bounded
(tests/bounded.py)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.schema import ScenarioError

from bounded import forked, sc_rt, sc_rt_process

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper_fault_free.toml"
MAX_FILE_BYTES = 1 << 20  # the documented limits (docs/SCENARIOS.md; sc_rt.scenario.files)
MAX_NESTING = 32


def _deep_arrays(d: Path) -> Path:
    f = d / "deep.toml"  # valid TOML whose arrays nest 200 levels deep, from line 3
    f.write_text('name = "deep"\n# arrays of arrays\nx = ' + "[\n" * 200 + "1" + "]" * 200 + "\n")
    return f


def _deep_keys(d: Path) -> Path:
    f = d / "dotted.toml"  # a dotted key 500 parts deep in a known table, on its last line
    f.write_text(PAPER.read_text() + "\n[laws.pd]\nkp" + ".a" * 500 + " = 1\n")
    return f


def _fifo(d: Path) -> Path:
    os.mkfifo(d / "fifo.toml")
    return d / "fifo.toml"


def _loop(d: Path) -> Path:
    (d / "a.toml").symlink_to("b.toml")
    (d / "b.toml").symlink_to("a.toml")
    return d / "a.toml"


def _large(d: Path) -> Path:
    f = d / "large.toml"  # 100 MB (sparse: zeros, nothing written)
    with open(f, "wb") as fh:
        fh.truncate(100 * 10**6)
    return f


def _just_over(d: Path) -> Path:
    f = d / "over.toml"  # a valid scenario padded with comments one byte past the limit
    text = PAPER.read_text() + "\n"
    pad = MAX_FILE_BYTES + 1 - len(text.encode())
    f.write_text(text + ("#" * 99 + "\n") * (pad // 100) + "#" * (pad % 100))
    assert f.stat().st_size == MAX_FILE_BYTES + 1
    return f


# (name, make the file in a folder -> its path, what the one line says, its line or None)
BAD_FILES = [
    ("dev-zero", lambda d: Path("/dev/zero"), "cannot read the file: a character device, not a regular file", None),
    ("fifo", _fifo, "cannot read the file: a FIFO (named pipe), not a regular file", None),
    ("directory", lambda d: d, "cannot read the file: a directory, not a regular file", None),
    ("symlink-loop", _loop, "cannot read the file: a symlink loop", None),
    ("100MB", _large, "cannot read the file: 100000000 bytes, larger than the limit of 1 MiB", None),
    ("limit+1", _just_over, f"{MAX_FILE_BYTES + 1} bytes, larger than the limit of 1 MiB", None),
    ("deep-arrays", _deep_arrays, f"TOML too deep: arrays and inline tables nest more than {MAX_NESTING} levels",
     3 + MAX_NESTING),
    ("deep-keys", _deep_keys, f"TOML too deep: laws.pd.kp... nests more than {MAX_NESTING} levels", "last"),
]


@pytest.mark.parametrize("make, says, line", [b[1:] for b in BAD_FILES], ids=[b[0] for b in BAD_FILES])
def test_a_bad_scenario_file_is_one_line_exit_2_and_nothing_runs(tmp_path, make, says, line):
    path = make(tmp_path)
    rc, lines, _ = sc_rt(["sim", str(path), "--out", "out", "--no-plots"], tmp_path)
    assert rc == 2 and len(lines) == 1, lines
    assert lines[0].startswith(f"sc-rt: {path}") and says in lines[0], lines
    if line == "last":
        line = len(path.read_text().splitlines())
    if line is not None:
        assert lines[0].startswith(f"sc-rt: {path}:{line}: "), lines
    assert not (tmp_path / "out").exists()  # nothing started


@pytest.mark.parametrize("which", ["dev-zero", "fifo", "deep-arrays"])
def test_sc_rt_check_reports_a_bad_file_as_an_error_with_file_and_line(tmp_path, which):
    _, make, says, line = next(b for b in BAD_FILES if b[0] == which)
    path = make(tmp_path)
    rc, lines, out = sc_rt(["check", str(path)], tmp_path)
    where = f"{path}:{line}" if line else f"{path}"
    assert rc == 2 and lines == [], lines
    assert out.splitlines()[0].startswith(f"ERROR   {where}: ") and says in out, out
    assert f"sc-rt check: {path}: 1 errors" in out, out


@pytest.mark.parametrize("cmd", ["hil", "montecarlo", "emulator"])
def test_every_command_taking_a_scenario_refuses_dev_zero(tmp_path, cmd):
    rc, lines, _ = sc_rt([cmd, "/dev/zero", "--out", "out"], tmp_path)
    assert rc == 2 and lines == ["sc-rt: /dev/zero: cannot read the file: a character device, not a regular file"]
    assert not (tmp_path / "out").exists()


def test_the_real_command_refuses_dev_zero_in_one_line(tmp_path):
    """The same through the installed entry point, a process of its own."""
    rc, lines = sc_rt_process(["sim", "/dev/zero", "--out", "out"], tmp_path)
    assert rc == 2 and lines == ["sc-rt: /dev/zero: cannot read the file: a character device, not a regular file"]
    assert not (tmp_path / "out").exists()


def test_a_symlink_to_a_scenario_is_followed_and_a_broken_one_named(tmp_path):
    (tmp_path / "mine.toml").symlink_to(PAPER)
    assert load_scenario(tmp_path / "mine.toml").name == "paper_fault_free"
    (tmp_path / "gone.toml").symlink_to(tmp_path / "nowhere.toml")
    os.chdir(tmp_path)
    try:  # a bare name that is a symlink is that file, not a shipped scenario's name
        with pytest.raises(ScenarioError, match=r"^gone.toml: cannot read the file: no such file$"):
            load_scenario("gone.toml")
    finally:
        os.chdir(ROOT)


def test_the_bounded_read_reads_the_file_and_stops_past_its_limit(tmp_path):
    from sc_rt.scenario import files
    from sc_rt.scenario.files import FileProblem, read_bounded

    assert (files.MAX_FILE_BYTES, files.MAX_NESTING) == (MAX_FILE_BYTES, MAX_NESTING)
    f = tmp_path / "x.toml"
    f.write_bytes(b"a" * 1000)
    assert read_bounded(f, 1000) == b"a" * 1000
    with pytest.raises(FileProblem, match="^1000 bytes, larger than the limit of"):
        read_bounded(f, 999)
    with pytest.raises(FileProblem, match="^a character device, not a regular file$"):
        read_bounded("/dev/urandom")


def test_a_shipped_scenario_is_far_within_the_limits():
    for f in (ROOT / "scenarios").glob("*.toml"):
        assert f.stat().st_size < MAX_FILE_BYTES / 20, f
        load_scenario(f)  # nesting: none deeper than a few levels


def test_a_reference_file_that_is_no_regular_file_or_too_large_is_refused(tmp_path):
    text = (ROOT / "scenarios" / "slew_rest_to_rest.toml").read_text()
    text = (text[: text.index("\n[guidance]\n")] + '\n[guidance]\nkind = "file"\nfile = "ref.csv"\n\n'
            + text[text.index("\n[controller.ppc]\n"):])
    scn = tmp_path / "s.toml"
    scn.write_text(text)

    def problem() -> str:  # in a child of its own (tests/bounded.py): a FIFO waited on fails, not hangs
        try:
            load_scenario(scn)
        except ScenarioError as e:
            return str(e)
        return "loaded"

    os.mkfifo(tmp_path / "ref.csv")
    assert "guidance.file" in (why := forked(problem, timeout=60)) and "a FIFO (named pipe)" in why, why
    os.unlink(tmp_path / "ref.csv")
    with open(tmp_path / "ref.csv", "wb") as fh:
        fh.truncate(50 * 10**6)
    assert "50000000 bytes, larger than the limit of 1 MiB" in (why := forked(problem, timeout=60)), why


def test_a_reference_npz_that_unpacks_beyond_the_limit_is_not_unpacked(tmp_path):
    import numpy as np

    from sc_rt.scenario.tables.reference_file import read_reference_file

    n = 200_000  # 4.8 MB of zeros unpacked, a few kB packed
    np.savez_compressed(tmp_path / "ref.npz", t=np.zeros(n), sigma=np.zeros((n, 3)), omega=np.zeros((n, 3)))
    assert (tmp_path / "ref.npz").stat().st_size < MAX_FILE_BYTES
    ref, problems = read_reference_file(tmp_path / "ref.npz")
    assert ref is None and "unpack to" in problems[0] and "more than the limit" in problems[0], problems


@pytest.mark.parametrize("name", ["dev-zero", "fifo", "missing"])
def test_report_refuses_a_log_that_is_not_a_regular_file(tmp_path, name):
    """sc-rt report LOG: /dev/zero and a FIFO are refused at once (exit 2,
    one line naming LOG and why; a FIFO would block a reader), nothing
    written; a missing log is named as missing."""
    log = {"dev-zero": Path("/dev/zero"), "fifo": tmp_path / "run.lcmlog", "missing": tmp_path / "none.lcmlog"}[name]
    if name == "fifo":
        os.mkfifo(log)
    rc, lines, _ = sc_rt(["report", str(log), "--out", "out"], tmp_path)
    why = "no such log file" if name == "missing" else "not a regular file (a log is one)"
    assert rc == 2 and lines == [f"sc-rt report: error: LOG {log}: {why}"], lines
    assert not (tmp_path / "out").exists()
