"""Plugin libraries validated before dlopen (issue 40, item 8; docs/LAWS.md):
a truncated library mapped by dlopen dies of SIGBUS (exit 135, no message)
when a page past its end is touched, in sim, hil, check, montecarlo and
sc-rt-controller alike; it is one line naming the file and what is wrong,
exit 2, instead. The library cut short is a real one built by this project
(the core's own module; a built law plugin in the slow test); loads run in
a child process, the commands bounded (tests/bounded.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from sc_rt import _core
from sc_rt.isolate import ChildDied, call_in_child
from sc_rt.scenario.reader import load_scenario

from bounded import sc_rt, sc_rt_process

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper_fault_free.toml"


def _library() -> Path:
    """A real shared library built by this project: the core's own module."""
    return Path(_core.__file__)


def _truncated(d: Path, keep: int, src: Path | None = None) -> Path:
    src = src or _library()
    f = d / f"libcut{keep}.so"
    with open(src, "rb") as a, open(f, "wb") as b:
        b.write(a.read(keep))
    return f


def _load_in_child(path: Path) -> str:
    """load_law_plugin's error in a child process (a SIGBUS there is a ChildDied, not this session's)."""
    try:
        call_in_child(_core.load_law_plugin, str(path))
    except ChildDied as e:
        return f"died: {e.how}"
    except ValueError as e:
        return str(e)
    return "loaded"


@pytest.mark.parametrize("fraction", [0.0, 0.001, 0.01, 0.3, 0.5, 0.8, 0.999])
def test_a_truncated_library_is_refused_before_dlopen(tmp_path, fraction):
    size = _library().stat().st_size
    f = _truncated(tmp_path, int(size * fraction))
    why = _load_in_child(f)
    assert why.startswith(f"law plugin:{f}: cannot load {f}: "), why
    if fraction >= 0.01:
        assert f"ends beyond the file's {int(size * fraction)} bytes: the file is truncated or damaged" in why, why


def test_a_truncated_library_without_section_headers_is_refused_by_its_segments(tmp_path):
    """The loader needs no section headers (a stripped one may have none): the
    mapped segments' file ranges are checked too."""
    import struct

    data = bytearray(_library().read_bytes())
    struct.pack_into("<Q", data, 0x28, 0)  # e_shoff: no section header table
    struct.pack_into("<HHH", data, 0x3A, 0, 0, 0)  # e_shentsize, e_shnum, e_shstrndx
    whole = tmp_path / "whole.so"
    whole.write_bytes(bytes(data))
    assert _core.plugin_file_problem(str(whole)) == ""
    f = _truncated(tmp_path, len(data) // 2, whole)
    why = _load_in_child(f)
    assert "its segment" in why and "(PT_LOAD, bytes" in why and "the file is truncated or damaged" in why, why


@pytest.mark.parametrize("what, make, says", [
    ("fifo", lambda d: (os.mkfifo(d / "lib.so"), d / "lib.so")[1], "is not a regular file"),
    ("directory", lambda d: (os.mkdir(d / "lib.so"), d / "lib.so")[1], "is not a regular file"),
    ("symlink-loop", lambda d: ((d / "lib.so").symlink_to("lib2.so"), (d / "lib2.so").symlink_to("lib.so"),
                                d / "lib.so")[2], "a symlink loop"),
    ("text", lambda d: ((d / "lib.so").write_text("not a library\n" * 10), d / "lib.so")[1], "(no ELF header)"),
    ("short", lambda d: ((d / "lib.so").write_bytes(b"\x7fELF"), d / "lib.so")[1], "4 bytes, shorter than an ELF"),
])
def test_a_plugin_path_that_is_no_library_is_named(tmp_path, what, make, says):
    f = make(tmp_path)
    why = _load_in_child(f)
    assert why.startswith(f"law plugin:{f}: ") and says in why, why


@pytest.mark.parametrize("cmd", [["sim", "paper_fault_free"], ["hil", "paper_fault_free"],
                                 ["check", "paper_fault_free"], ["montecarlo", "paper_fault_free", "--runs", "2"],
                                 ["compare", "paper_fault_free", "--law", "pd"]])
@pytest.mark.parametrize("given", ["option", "scenario"])
def test_every_command_refuses_a_truncated_plugin_in_one_line(tmp_path, cmd, given):
    lib = _truncated(tmp_path, 200_000)
    args = [*cmd, "--law", f"plugin:{lib}"]
    if given == "scenario":  # the scenario names it (relative to the file)
        scn = tmp_path / "s.toml"
        scn.write_text(PAPER.read_text().replace('controller = "dsc-ppc"', f'controller = "plugin:{lib.name}"', 1))
        assert f'controller = "plugin:{lib.name}"' in scn.read_text()
        args = [cmd[0], str(scn), *cmd[2:]]
        if cmd[0] == "compare":
            args += ["--law", "dsc"]
    rc, lines, out = sc_rt(args if cmd[0] == "check" else [*args, "--out", "out"], tmp_path)
    text = "\n".join(lines) + out
    assert rc == 2, (rc, text)  # not 135 (SIGBUS)
    assert f"cannot load {lib}: " in text and "the file is truncated or damaged" in text, text
    assert len(lines) == (0 if cmd[0] == "check" and given == "scenario" else 1), lines
    assert not (tmp_path / "out").exists()


def test_the_cpp_controller_refuses_a_truncated_plugin(tmp_path):
    cfg = tmp_path / "cfg.bin"
    cfg.write_bytes(load_scenario("paper_fault_free").controller_config_msg().encode())
    lib = _truncated(tmp_path, 200_000)
    exe = Path(sys.executable).parent / "sc-rt-controller"
    r = subprocess.run([str(exe), "--config", str(cfg), "--check", "--law-plugin", str(lib)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "the file is truncated or damaged" in r.stderr and str(lib) in r.stderr, r


def test_a_truncated_copy_of_a_built_plugin_is_refused(plugins, tmp_path):
    """The real thing: a law plugin built as a user's is, cut short."""
    src = plugins["qf"]
    assert _load_in_child(src) == "loaded"
    for keep in (src.stat().st_size // 3, src.stat().st_size - 1):
        f = _truncated(tmp_path, keep, src)
        why = _load_in_child(f)
        assert why.startswith(f"law plugin:{f}: cannot load {f}: ") and "truncated or damaged" in why, why


def test_the_real_command_refuses_a_truncated_plugin_in_one_line(tmp_path):
    """Through the installed entry point, a process of its own."""
    lib = _truncated(tmp_path, 200_000)
    rc, lines = sc_rt_process(["sim", "paper_fault_free", "--law", f"plugin:{lib}", "--out", "out"], tmp_path)
    assert rc == 2 and len(lines) == 1 and "the file is truncated or damaged" in lines[0], (rc, lines)
    assert not (tmp_path / "out").exists()
