"""Every subcommand's numeric and path options with bad values (0, negative,
nan, inf, 1e9, a wrong type, an output path that is a file or lies under
one): exit code 2, one line on stderr naming the option and the value,
nothing written, no child process (table-driven, sc_rt.cli.validate)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import psutil
import pytest

from sc_rt.cli.main import main

import lcmnet

# value kinds: the bad values each option gets
POSITIVE = ("0", "-1", "nan", "inf", "1e9", "abc")  # a rate, a time scale, a speed: 1e9 is beyond its limit
LENGTH = ("0", "-1", "nan", "inf", "abc")  # a duration or a step: 1e9 is refused by the run's size (below)
UNIT = ("-0.1", "1.5", "nan", "inf", "abc")  # in [0, 1]
COUNT = ("0", "-1", "1.5", "abc", "1e9")  # an integer >= 1 with an upper limit
TIME = ("-1", "nan", "inf", "abc")  # a simulation time >= 0
FINITE = ("nan", "inf", "abc")

LOG = "some.lcmlog"

# (command and its positional arguments, option, kind)
OPTIONS = [
    (["sim", "paper_faults"], "--control-rate", POSITIVE),
    (["sim", "paper_faults"], "--duration", LENGTH),
    (["sim", "paper_faults"], "--plant-step", LENGTH),
    (["hil", "paper_faults"], "--control-rate", POSITIVE),
    (["hil", "paper_faults"], "--duration", LENGTH),
    (["hil", "paper_faults"], "--time-scale", POSITIVE),
    (["emulator", "paper_faults"], "--rate", POSITIVE),
    (["emulator", "paper_faults"], "--time-scale", POSITIVE),
    (["emulator", "paper_faults"], "--duration", LENGTH),
    (["config", "paper_faults", "--out", "c.bin"], "--control-rate", POSITIVE),
    (["design", "paper_faults"], "--rate", POSITIVE),
    (["design", "paper_faults"], "--latency", POSITIVE),
    (["reproduce"], "--control-rate", POSITIVE),
    (["reproduce"], "--plant-step", LENGTH),
    (["reproduce"], "--dpi", COUNT),
    (["spy"], "--duration", POSITIVE),
    (["spy"], "--refresh", POSITIVE),
    (["spy"], "--window", POSITIVE),
    (["replay", LOG], "--speed", POSITIVE),
    (["fault", "inject", "--bias", "0.1"], "--wheel", ("0", "5", "-1", "abc", "1e9")),
    (["fault", "inject", "--wheel", "1"], "--effectiveness", UNIT),
    (["fault", "inject", "--wheel", "1", "--effectiveness", "0.5"], "--bias", FINITE),
    (["fault", "inject", "--wheel", "1", "--effectiveness", "0.5"], "--rate", ("0", "-1", "nan", "inf", "abc")),
    (["fault", "inject", "--wheel", "1", "--effectiveness", "0.5"], "--at", TIME),
    (["fault", "inject", "--wheel", "1", "--effectiveness", "0.5"], "--until", TIME),
    (["fault", "inject", "--wheel", "1", "--effectiveness", "0.5"], "--timeout", POSITIVE),
    (["fault", "clear"], "--wheel", ("0", "5", "abc")),
    (["fault", "clear", "--wheel", "1"], "--timeout", POSITIVE),
    (["montecarlo", "paper_faults"], "--runs", COUNT),
    (["montecarlo", "paper_faults"], "--workers", COUNT),
    (["montecarlo", "paper_faults"], "--batch", COUNT),
    (["montecarlo", "paper_faults"], "--seed", ("-1", "1.5", "abc")),
    (["montecarlo", "paper_faults"], "--rerun", ("-1", "abc")),
    (["montecarlo", "paper_faults"], "--control-rate", ("0", "-1", "nan", "inf", "abc")),
    (["montecarlo", "paper_faults"], "--inertia", ("-0.1", "1", "nan", "inf", "abc")),
    (["montecarlo", "paper_faults"], "--onset", ("-1", "nan", "inf", "abc")),
    (["montecarlo", "paper_faults"], "--effectiveness", UNIT),
    (["montecarlo", "paper_faults"], "--attitude", ("-0.1", "4", "nan", "inf", "abc")),
    (["montecarlo", "paper_faults"], "--rate", ("-1", "nan", "inf", "abc")),
    (["compare", "paper_faults", "--law", "pd", "--law", "dsc"], "--duration", LENGTH),
    (["compare", "paper_faults", "--law", "pd", "--law", "dsc"], "--settle", ("0", "-1", "1", "nan", "inf", "abc")),
    (["controller", "--law", str(lcmnet.ROOT / "examples/python_laws/pd.py") + ":PythonPD", "paper_faults"],
     "--control-rate", POSITIVE),
    (["controller", "--law", str(lcmnet.ROOT / "examples/python_laws/pd.py") + ":PythonPD", "paper_faults"],
     "--max-steps", ("0", "-1", "abc", "1e99")),
    (["controller", "--law", str(lcmnet.ROOT / "examples/python_laws/pd.py") + ":PythonPD", "paper_faults"],
     "--cpu", ("-1", "1.5", "abc")),
]
NUMERIC = [(pre, opt, v) for pre, opt, values in OPTIONS for v in values]

URLS = ("nonsense", "udpm://10.0.0.1:7667", "udpm://239.255.76.67:99999", "udpm://239.255.76.67:7667?ttl=999")
URL_COMMANDS = (["hil", "paper_faults"], ["demo"], ["emulator", "paper_faults"], ["spy"], ["replay", LOG],
                ["fault", "clear", "--wheel", "1"], ["lcm-spy"])

# the size of a run, refused before it starts with the numbers (rows x bytes per
# row against the memory, or a bench run's against the disk, plant steps, the real-time tick)
SIZES = [
    (["sim", "paper_faults", "--control-rate", "100000", "--duration", "5000"], "--duration 5000",
     "of memory available"),
    (["sim", "paper_faults", "--duration", "1e9"], "--duration 1e+09", "plant steps"),
    (["sim", "paper_faults", "--plant-step", "1e-9"], "--plant-step 1e-09", "plant steps"),
    (["hil", "paper_faults", "--control-rate", "100000", "--duration", "5000"], "--control-rate 100000",
     "on disk at most"),  # the bench writes its rows as it runs: its disk, not its memory
    (["hil", "paper_faults", "--mode", "realtime", "--control-rate", "1000", "--time-scale", "1000"],
     "--time-scale 1000", "cannot tick faster"),
    (["emulator", "paper_faults", "--rate", "100000", "--duration", "5000"], "--rate 100000",
     "on disk at most"),
    (["montecarlo", "paper_faults", "--control-rate", "100000", "--workers", "1000"], "--control-rate 100000",
     "of memory available"),
    (["compare", "paper_faults", "--law", "pd", "--law", "dsc", "--duration", "1e8"], "--duration 1e+08",
     "of memory available"),
]


@pytest.fixture
def cli(tmp_path, capsys, monkeypatch):
    """sc-rt ARGS in this process, from an empty directory: (exit code,
    stderr lines); checks that nothing was written and no child is left."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("SCRT_LCM_URL", "memq://")
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}

    def run(args: list[str]) -> tuple[int, list[str]]:
        capsys.readouterr()
        before = {p.pid for p in psutil.Process().children(recursive=True)}
        try:
            rc = main(args)
        except SystemExit as e:
            rc = e.code
        finally:
            for s, h in handlers.items():
                signal.signal(s, h)
        err = capsys.readouterr().err
        started = [p for p in psutil.Process().children(recursive=True) if p.pid not in before]
        assert started == [], f"{args} left {started}"
        assert sorted(os.listdir(tmp_path)) == sorted(set(os.listdir(tmp_path)) & {"afile"}), \
            f"{args} wrote {os.listdir(tmp_path)}"
        return rc, err.strip().splitlines()

    return run


def _names(line: str, option: str, value: str) -> bool:
    try:
        alt = f"{float(value):g}"
    except ValueError:
        alt = value
    return option in line and (value in line or alt in line)


@pytest.mark.parametrize("pre, option, value", NUMERIC, ids=[f"{p[0]}{o}={v}" for p, o, v in NUMERIC])
def test_bad_number_exits_2_naming_option_and_value(cli, pre, option, value):
    rc, lines = cli([*pre, option, value])
    assert rc == 2, lines
    assert len(lines) == 1, lines
    assert _names(lines[0], option, value), lines
    assert lines[0].startswith("sc-rt"), lines


@pytest.mark.parametrize("pre, url", [(p, u) for p in URL_COMMANDS for u in URLS])
def test_bad_lcm_url_exits_2(cli, pre, url):
    rc, lines = cli([*pre, "--lcm-url", url])
    assert rc == 2 and len(lines) == 1 and "--lcm-url" in lines[0] and url in lines[0], lines


def test_bad_scrt_lcm_url_is_named(cli, monkeypatch):
    monkeypatch.setenv("SCRT_LCM_URL", "udpm://10.1.2.3:7667")
    rc, lines = cli(["fault", "clear", "--wheel", "1"])
    assert rc == 2 and len(lines) == 1 and "SCRT_LCM_URL=udpm://10.1.2.3:7667" in lines[0], lines


OUT_DIRS = [["sim", "paper_faults"], ["hil", "paper_faults"], ["demo"], ["emulator", "paper_faults"],
            ["design", "paper_faults"], ["reproduce"], ["report", LOG], ["montecarlo", "paper_faults"],
            ["compare", "paper_faults", "--law", "pd", "--law", "dsc"], ["new-law", "my-law"]]


@pytest.mark.parametrize("pre", OUT_DIRS, ids=[p[0] for p in OUT_DIRS])
@pytest.mark.parametrize("where", ["afile", "afile/sub"])
def test_out_dir_that_is_a_file_exits_2(cli, tmp_path, pre, where):
    (tmp_path / "afile").write_text("not a directory\n")
    rc, lines = cli([*pre, "--out", where])
    assert rc == 2 and len(lines) == 1, lines
    assert "--out" in lines[0] and where in lines[0] and "not a directory" in lines[0], lines


@pytest.mark.parametrize("where, why", [(".", "is a directory"), ("afile/c.bin", "not a directory")])
def test_config_out_file_exits_2(cli, tmp_path, where, why):
    (tmp_path / "afile").write_text("x\n")
    rc, lines = cli(["config", "paper_faults", "--out", where])
    assert rc == 2 and len(lines) == 1 and "--out" in lines[0] and why in lines[0], lines


@pytest.mark.parametrize("args, names, why", SIZES, ids=[" ".join(a[:1] + a[2:]) for a, _, _ in SIZES])
def test_a_run_too_large_is_refused_with_the_numbers(cli, args, names, why):
    rc, lines = cli(args)
    assert rc == 2 and len(lines) == 1, lines
    assert names in lines[0] and why in lines[0], lines


@pytest.mark.parametrize("cmd", [["sim"], ["hil"], ["emulator"], ["check"], ["montecarlo"]])
def test_a_scenario_too_long_is_refused(cli, tmp_path, cmd):
    """A scenario value, not an option: its run's size is checked the same way."""
    text = (lcmnet.ROOT / "scenarios" / "paper_faults.toml").read_text()
    assert "duration = 300.0" in text
    (tmp_path / "afile").write_text(text.replace("duration = 300.0", "duration = 1e8", 1))
    rc, lines = cli([*cmd, "afile"])
    assert rc == 2 and len(lines) == 1, lines
    why = "on disk at most" if cmd[0] in ("hil", "emulator") else "of memory available"
    assert "rows (1e+08 s at 10 Hz)" in lines[0] and why in lines[0], lines


@pytest.mark.parametrize("args", [["reproduce", "--control-rate", "100000"],
                                  ["reproduce", "--plant-step", "1e-9"]])
def test_reproduce_refuses_runs_that_cannot_fit(cli, args):
    rc, lines = cli(args)
    assert rc == 2 and len(lines) == 1 and args[1] in lines[0], lines


def test_readonly_out_dir_exits_2(cli, tmp_path):
    if os.geteuid() == 0:  # root writes anywhere but on a read-only mount: use one
        r = subprocess.run(["unshare", "-m", "sh", "-c",
                            f"mkdir -p ro && mount -t tmpfs -o ro,size=64k tmpfs ro && "
                            f"{sys.executable} -m sc_rt.cli sim paper_faults --out ro/x"],
                           capture_output=True, text=True, cwd=tmp_path)
        if "mount" in r.stderr and r.returncode != 2:
            pytest.skip(f"cannot mount a tmpfs here: {r.stderr}")
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and "not writable" in lines[0], r.stderr
        assert not (tmp_path / "ro").is_mount()  # the mount stayed in its namespace
        return
    ro = tmp_path / "ro"
    ro.mkdir(mode=0o500)
    rc, lines = cli(["sim", "paper_faults", "--out", "ro/x"])
    assert rc == 2 and "not writable" in lines[0], lines


def test_hil_refused_starts_no_process(tmp_path):
    """The real command, in its own network namespace: a refused run starts
    neither the controller nor the logger and writes nothing."""
    lcmnet.require()
    out = tmp_path / "unique-hil-out"
    r = lcmnet.run_cli(["hil", "paper_faults", "--control-rate", "100000", "--duration", "5000",
                        "--out", str(out)], timeout=120)
    assert r.returncode == 2 and "on disk at most" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not out.exists()
    left = subprocess.run(["pgrep", "-f", str(out)], capture_output=True, text=True)
    assert left.returncode == 1, left.stdout


def test_scrt_lcm_url_is_the_url_of_hil_and_emulator(tmp_path):
    """$SCRT_LCM_URL when no --lcm-url: the run is on that URL (it says so)."""
    lcmnet.require()
    url = "udpm://239.255.76.67:7831?ttl=0"
    env = dict(os.environ, SCRT_LCM_URL=url)
    cli = [sys.executable, "-m", "sc_rt.cli"]
    r = lcmnet.run([*cli, "hil", "paper_fault_free", "--duration", "2", "--no-plots", "--out", str(tmp_path / "h")],
                   timeout=120, env=env)
    assert r.returncode == 0 and f"sc-rt hil: LCM URL {url}" in r.stderr, r.stderr
    r = lcmnet.run([*cli, "emulator", "paper_fault_free", "--mode", "realtime", "--rate", "20", "--duration",
                    "0.2"], timeout=120, env=env)
    assert r.returncode == 0 and f"sc-rt emulator: LCM URL {url}" in r.stderr, r.stderr
