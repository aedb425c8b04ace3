"""Sanitizer builds of the C++ (issue #24, item 6).

AddressSanitizer + UBSan (build/asan): sc-rt-controller
in lockstep and real time against the Python emulator (with the sensors'
MEKF, authentication, a configuration on SCRT_CONFIG and a hostile publisher
on every channel it reads), its configuration decoder on corrupted files, the
LCM round-trip tool, and the C++-heavy test files in-process against the
sanitized sc_rt._core. ThreadSanitizer (build/tsan): sc-rt-controller in real
time, whose receive thread and step thread share the shell, over loopback.

Each build is incremental in its own folder (cmake/Sanitizers.cmake, option
SC_RT_SANITIZE); `make check-sanitizers` runs this file alone. A run passes
only with exit status 0 and no sanitizer report in any process's output; the
canary (tools/sanitizers/canary.cpp) proves that a bug does fail it.
"""

from __future__ import annotations

import json
import os
import random
import re
import shlex
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

import lcmnet
from ctlscript import controller_config as _config, wait_for_line as _wait_for

pytestmark = pytest.mark.slow  # ~2 min once built; the builds from scratch ~6 min on 2 cores

ROOT = Path(__file__).resolve().parent.parent
HERE = Path(__file__).resolve().parent
BIN = Path(sys.executable).parent  # the venv: cmake and ninja (the build requirements), sc-rt
PY = shlex.quote(sys.executable)
SHIM = ROOT / "tools" / "sanitizers" / "pyshim"
BUILD_TIMEOUT = 3600  # a cold sanitizer build of everything: ~6 min on 2 idle cores

# What a report looks like, whichever runtime wrote it.
REPORT = re.compile(r"ERROR: (Address|Leak)Sanitizer|WARNING: ThreadSanitizer|runtime error:|"
                    r"SUMMARY: (Address|Leak|Thread|UndefinedBehavior)Sanitizer")
# Every finding fails the run at once; leaks are checked at the controller's exit.
ASAN_ENV = {
    "ASAN_OPTIONS": "detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1:"
                    "check_initialization_order=1:strict_init_order=1:halt_on_error=1",
    "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1",
}
TSAN_ENV = {"TSAN_OPTIONS": "halt_on_error=1 exitcode=66 second_deadlock_stack=1 "
                            f"suppressions={ROOT / 'tools' / 'sanitizers' / 'tsan.supp'}"}


def _build(kind: str, sanitize: str, targets: list[str]) -> Path:
    """build/<kind> with -DSC_RT_SANITIZE=<sanitize>: configure (cheap when
    cached), then build only `targets`. -O1 -g without NDEBUG: readable
    stacks, and Eigen's own bound checks (eigen_assert) on."""
    d = ROOT / "build" / kind
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}
    gen = [] if (d / "CMakeCache.txt").exists() else ["-G", "Ninja"]  # the venv's ninja; a cache keeps its own
    cfg = [str(BIN / "cmake"), "-S", str(ROOT), "-B", str(d), *gen,
           f"-DPython_EXECUTABLE={sys.executable}", f"-DSC_RT_SANITIZE={sanitize}",
           "-DCMAKE_BUILD_TYPE=RelWithDebInfo", "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g"]
    for cmd in (cfg, [str(BIN / "cmake"), "--build", str(d), "-j2", "--target", *targets]):
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=BUILD_TIMEOUT)
        if r.returncode != 0:
            pytest.fail(f"{' '.join(cmd)}:\n{(r.stdout + r.stderr)[-5000:]}", pytrace=False)
    return d


@pytest.fixture(scope="module")
def asan() -> Path:
    return _build("asan", "address,undefined",
                  ["sc-rt-controller", "sc-rt-lcm-pingpong", "_core", "sc-rt-sanitizer-canary"])


@pytest.fixture(scope="module")
def tsan() -> Path:
    return _build("tsan", "thread", ["sc-rt-controller", "sc-rt-sanitizer-canary"])


def _clean(text: str, what: str) -> None:
    m = REPORT.search(text)
    assert m is None, f"{what}: sanitizer report:\n{text[max(0, m.start() - 2000):m.start() + 8000]}"


def _symbols(path: Path) -> str:
    return subprocess.run(["nm", "-D", "--undefined-only", str(path)], capture_output=True, text=True,
                          check=True).stdout


def _runtime(name: str) -> str:
    """The compiler's shared sanitizer runtime (gcc-12: libasan.so.8, libubsan.so.1)."""
    p = subprocess.run(["g++", f"-print-file-name={name}"], capture_output=True, text=True).stdout.strip()
    assert os.path.isabs(p) and os.path.exists(p), f"g++ has no {name} (Debian: gcc-12 ships it)"
    return os.path.realpath(p)


# ---------------------------------------------------------------- the proofs


@pytest.mark.parametrize("bug, report", [
    ("heap-overflow", r"AddressSanitizer: heap-buffer-overflow|runtime error: load of address .* insufficient space"),
    ("use-after-free", r"AddressSanitizer: heap-use-after-free"),
    ("leak", r"LeakSanitizer: detected memory leaks"),
    ("signed-overflow", r"runtime error: signed integer overflow"),
    ("float-cast", r"runtime error: .* is outside the range of representable values"),
])
def test_asan_build_is_instrumented_and_a_bug_fails_the_run(asan, bug, report):
    for exe in (asan / "cpp" / "sc-rt-controller", next((asan / "cpp").glob("_core*.so"))):
        syms = _symbols(exe)
        assert "__asan_init" in syms and "__ubsan_handle_" in syms, exe
    canary = asan / "sc-rt-sanitizer-canary"
    ok = subprocess.run([str(canary), "ok"], capture_output=True, text=True, env={**os.environ, **ASAN_ENV})
    assert ok.returncode == 0 and "survived" in ok.stdout, ok.stderr
    r = subprocess.run([str(canary), bug], capture_output=True, text=True, env={**os.environ, **ASAN_ENV})
    assert r.returncode != 0 and "survived" not in r.stdout, (r.returncode, r.stdout)
    assert re.search(report, r.stderr), r.stderr
    with pytest.raises(AssertionError):
        _clean(r.stderr, "canary")


def test_tsan_build_is_instrumented_and_a_race_fails_the_run(tsan):
    assert "__tsan_init" in _symbols(tsan / "cpp" / "sc-rt-controller")
    env = {**os.environ, **TSAN_ENV}
    ok = subprocess.run([str(tsan / "sc-rt-sanitizer-canary"), "ok"], capture_output=True, text=True, env=env)
    # gcc 12's TSan runtime cannot map its shadow under a kernel with more
    # ASLR entropy than 28 bits (vm.mmap_rnd_bits; Debian 12's is 28)
    assert "unexpected memory mapping" not in ok.stderr, \
        "TSan cannot run here: sysctl -w vm.mmap_rnd_bits=28 (or run it under setarch -R)"
    assert ok.returncode == 0, ok.stderr
    r = subprocess.run([str(tsan / "sc-rt-sanitizer-canary"), "race"], capture_output=True, text=True, env=env)
    assert r.returncode == 66 and "WARNING: ThreadSanitizer: data race" in r.stderr, (r.returncode, r.stderr)


# ------------------------------------------------- the controller under ASan


def _bench(script: str, tmp: Path, env: dict[str, str], timeout: float = 600) -> str:
    """A shell script in a private network namespace (tests/lcmnet.py); the
    controller's stderr goes to tmp/ctl*.err. Returns all of it, checked clean."""
    lcmnet.require()
    r = lcmnet.run_script(script, timeout=timeout, env={**os.environ, **env})
    errs = "".join(f"--- {p.name}\n{p.read_text(errors='replace')}" for p in sorted(tmp.glob("ctl*.err")))
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:] + errs[-8000:]
    _clean(errs + r.stderr, "sc-rt-controller")
    return errs


def test_asan_controller_lockstep_sensors_auth_and_config_channel(asan, tmp_path):
    """The configuration arrives tagged on SCRT_CONFIG (--config-channel
    --auth-key); a lockstep run with the MEKF on the sensor messages, every
    message authenticated."""
    ctl = shlex.quote(str(asan / "cpp" / "sc-rt-controller"))
    url = "udpm://239.255.76.67:7751?ttl=0&recv_buf_size=4194304"
    scn = "ppc_feasible_100hz_sensors"
    cfg = _config(scn, tmp_path / "cfg.bin")
    key = tmp_path / "key"
    key.write_bytes(bytes(random.Random(24).getrandbits(8) for _ in range(32)))
    publish = (f"import lcm, time; from sc_rt.wire.auth import message_tag; d = open('{cfg}', 'rb').read(); "
               f"lc = lcm.LCM('{url}'); k = open('{key}', 'rb').read(); "
               f"[lc.publish('SCRT_CONFIG', d + message_tag(k, 'SCRT_CONFIG', d)) or time.sleep(0.05) "
               f"for _ in range(10)]")
    script = f"""
set -e
{ctl} --config-channel --auth-key {key} --lcm-url '{url}' --summary {tmp_path}/sum.json \\
    > /dev/null 2> {tmp_path}/ctl.err &
CTL=$!
{_wait_for('waiting for', tmp_path / 'ctl.err')}
{PY} -c {shlex.quote(publish)}
{_wait_for('mode on', tmp_path / 'ctl.err')}
{PY} -m sc_rt.cli emulator {scn} --lcm-url '{url}' --auth-key {key} --duration 20 --out {tmp_path}/emu \\
    > {tmp_path}/emu.log 2>&1
kill -TERM $CTL
wait $CTL
"""
    _bench(script, tmp_path, ASAN_ENV)
    s = json.loads((tmp_path / "sum.json").read_text())
    assert s["auth"] and s["auth_failed"] == 0 and s["steps"] == 20 * 100 + 1, s
    assert s["nav"]["measurement"] == "estimate" and s["nav"]["gyro_used"] > 0 and s["nav"]["star_used"] > 0, s


def test_asan_controller_lockstep_under_a_hostile_publisher(asan, tmp_path):
    """20,000 malformed, truncated, foreign, replayed and non-finite messages
    on the state and sensor channels while a lockstep run goes on: every one
    goes through the controller's decoders and the gates."""
    ctl = shlex.quote(str(asan / "cpp" / "sc-rt-controller"))
    url = "udpm://239.255.76.67:7752?ttl=0&recv_buf_size=4194304"
    scn = "ppc_feasible_100hz_sensors"  # 10,001 steps in ~4 s: the storm falls inside the run
    cfg = _config(scn, tmp_path / "cfg.bin")
    script = f"""
set -e
{ctl} --config {cfg} --lcm-url '{url}' --summary {tmp_path}/sum.json > /dev/null 2> {tmp_path}/ctl.err &
CTL=$!
{_wait_for('mode on', tmp_path / 'ctl.err')}
{PY} -m sc_rt.cli emulator {scn} --lcm-url '{url}' --duration 100 --out {tmp_path}/emu > {tmp_path}/emu.log 2>&1 &
EMU=$!
SCRT_WAIT_PID=$EMU {PY} {HERE / 'fuzz_lcm.py'} '{url}' 20000 {tmp_path}/sent.json 7 \\
    SCRT_STATE,SCRT_GYRO,SCRT_STAR,SCRT_TACH
wait $EMU
kill -TERM $CTL
wait $CTL
"""
    _bench(script, tmp_path, ASAN_ENV)
    s = json.loads((tmp_path / "sum.json").read_text())
    assert s["steps"] == 10001, s
    assert s["rejected"]["malformed"] > 0 and s["rejected"]["foreign_session"] > 0, s
    assert s["nav"]["rejected"]["malformed"] > 0 and s["nav"]["rejected"]["invalid"] > 0, s


@pytest.mark.parametrize("trigger, port", [("timer", 7753), ("event", 7755)])
def test_asan_controller_realtime_and_the_lcm_round_trip_tool(asan, tmp_path, trigger, port):
    """Real time at 100 Hz with the sensors, both triggers (the timer's
    receive thread and loop; the event trigger, the default, stepping on
    each arrival), stopped by SIGTERM: the leak check runs at its exit.
    Then sc-rt-lcm-pingpong, both roles."""
    ctl = shlex.quote(str(asan / "cpp" / "sc-rt-controller"))
    pp = shlex.quote(str(asan / "cpp" / "sc-rt-lcm-pingpong"))
    url = f"udpm://239.255.76.67:{port}?ttl=0&recv_buf_size=4194304"
    scn = "ppc_feasible_100hz_sensors"
    cfg = _config(scn, tmp_path / "cfg.bin")
    script = f"""
set -e
{ctl} --config {cfg} --mode realtime --trigger {trigger} --lcm-url '{url}' --summary {tmp_path}/sum.json \\
    > /dev/null 2> {tmp_path}/ctl.err &
CTL=$!
{_wait_for('mode on', tmp_path / 'ctl.err')}
{PY} -m sc_rt.cli emulator {scn} --mode realtime --lcm-url '{url}' --duration 4 > {tmp_path}/emu.log 2>&1
kill -TERM $CTL
wait $CTL
{pp} --role pong --lcm-url '{url}' 2> {tmp_path}/ctl-pong.err &
PONG=$!
{_wait_for('pong ready', tmp_path / 'ctl-pong.err')}
{pp} --role ping --lcm-url '{url}' --count 300 > {tmp_path}/ping.json 2> {tmp_path}/ctl-ping.err
kill -TERM $PONG
wait $PONG
"""
    _bench(script, tmp_path, ASAN_ENV)
    s = json.loads((tmp_path / "sum.json").read_text())
    assert s["mode"] == "realtime" and s["trigger"] == trigger and s["steps"] >= 200 and s["nav"]["gyro_used"] > 0, s
    assert json.loads((tmp_path / "ping.json").read_text())["n"] > 0


def test_asan_controller_config_decoder_on_corrupted_files(asan, tmp_path):
    """--check on truncated, bit-flipped and random configurations: each is
    accepted or refused with exit 2, never a crash or a report."""
    good = _config("paper_faults_sensors", tmp_path / "cfg.bin").read_bytes()
    rng = random.Random(20240624)
    variants = [good[:n] for n in sorted(rng.sample(range(len(good)), 30))]
    for _ in range(30):
        b = bytearray(good)
        for _ in range(rng.randrange(1, 8)):
            b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
        variants.append(bytes(b))
    variants += [rng.randbytes(rng.randrange(1, 2000)) for _ in range(10)]
    variants.append(good + b"\x00" * 7)
    env = {**os.environ, **ASAN_ENV}
    codes = []
    for i, v in enumerate(variants):
        f = tmp_path / f"v{i}.bin"
        f.write_bytes(v)
        r = subprocess.run([str(asan / "cpp" / "sc-rt-controller"), "--config", str(f), "--check"],
                           capture_output=True, text=True, env=env, timeout=60)
        _clean(r.stderr, f"--check on variant {i}")
        assert r.returncode in (0, 2), (i, r.returncode, r.stderr[-3000:])
        codes.append(r.returncode)
    assert 2 in codes  # the truncations at least are refused


# ------------------------------------------------- the bindings under ASan

# The test files that exercise the C++ through sc_rt._core in-process (the
# laws, the plant, the sensors and the MEKF, the shell's policy, the packed
# layouts, the C++ engine of sim); only their fast, in-process tests: the
# slow and LCM ones start processes (the unsanitized controller among them).
CORE_TESTS = ["test_controllers.py", "test_laws.py", "test_references.py", "test_plant.py", "test_ppc.py",
              "test_actuators.py", "test_sensors.py", "test_packed_layout.py", "test_mrp.py", "test_neso.py",
              "test_mekf.py", "test_shell_policy.py", "test_sensor_intake.py", "test_auth.py", "test_pylaw.py",
              "test_sim.py", "test_wheels.py", "test_torque_plant.py", "test_flight_wheels.py",
              "test_mag_plant_twin.py", "test_mag_plant.py", "test_mag_rods.py", "test_stribeck_switching.py",
               "test_mag_control.py", "test_mag_detumble.py", "test_wmm2025.py", "test_mag_sensed.py"]


def _asan_python_env(asan: Path, logs: Path) -> dict[str, str]:
    """This interpreter with the ASan and UBSan runtimes preloaded (it is not
    instrumented itself) and the sanitized _core in place of the installed
    one (tools/sanitizers/pyshim). Reports go to logs/ from every process of
    the run. No leak check: CPython keeps its allocations to the end."""
    core = next((asan / "cpp").glob("_core*" + sysconfig.get_config_var("EXT_SUFFIX")))
    return {
        **os.environ,
        "LD_PRELOAD": f"{_runtime('libasan.so')} {_runtime('libubsan.so')}",
        "ASAN_OPTIONS": f"detect_leaks=0:halt_on_error=1:log_path={logs}/asan",
        "UBSAN_OPTIONS": f"print_stacktrace=1:halt_on_error=1:log_path={logs}/ubsan",
        "SCRT_SANITIZED_CORE": str(core),
        "PYTHONPATH": os.pathsep.join(filter(None, [str(SHIM), os.environ.get("PYTHONPATH")])),
    }


def test_asan_bindings_run_the_core_tests(asan, tmp_path):
    logs = tmp_path / "logs"
    logs.mkdir()
    env = _asan_python_env(asan, logs)
    # a heap overflow in a process of this environment is a report in logs/
    # (through the preloaded runtime's memmove interceptor)
    canary = tmp_path / "canary-logs"
    canary.mkdir()
    bug = ("import ctypes; libc = ctypes.CDLL(None); libc.malloc.restype = ctypes.c_void_p; "
           "ctypes.memmove(libc.malloc(8), b'x' * 32, 32)")
    r = subprocess.run([sys.executable, "-c", bug], capture_output=True, text=True,
                       env=_asan_python_env(asan, canary))
    assert r.returncode != 0 and "heap-buffer-overflow" in "".join(p.read_text() for p in canary.iterdir())
    # the interpreter really runs the sanitized module
    r = subprocess.run([sys.executable, "-c", "from sc_rt import _core; print(_core.__file__)"],
                       capture_output=True, text=True, env=env, cwd=ROOT)
    assert r.returncode == 0 and r.stdout.strip() == env["SCRT_SANITIZED_CORE"], r.stdout + r.stderr
    files = [str(HERE / t) for t in CORE_TESTS if (HERE / t).exists()]
    assert len(files) >= len(CORE_TESTS) - 3, "CORE_TESTS names files that are gone: update it"
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                        "-m", "not slow and not lcm", *files],
                       capture_output=True, text=True, env=env, cwd=ROOT, timeout=1800)
    reports = "".join(p.read_text(errors="replace") for p in sorted(logs.iterdir()))
    assert not reports, f"sanitizer reports:\n{reports[:20000]}"
    _clean(r.stdout + r.stderr, "pytest under ASan")
    assert r.returncode == 0, r.stdout[-6000:] + r.stderr[-3000:]
    assert re.search(r"\d+ passed", r.stdout), r.stdout[-2000:]


# ------------------------------------------------- the controller under TSan


@pytest.mark.parametrize("trigger, port", [("timer", 7754), ("event", 7756)])
def test_tsan_controller_realtime_threads(tsan, tmp_path, trigger, port):
    """Real time, both triggers: the receive thread (states and sensor
    messages into the mailbox and the MEKF's intake) against the step thread
    (the law, the estimator, publishing), or with the event trigger LCM's
    own thread against the stepping one, at 100 Hz with authentication;
    then without it, under a hostile publisher on the state and sensor
    channels."""
    ctl = shlex.quote(str(tsan / "cpp" / "sc-rt-controller"))
    url = f"udpm://239.255.76.67:{port}?ttl=0&recv_buf_size=4194304"
    scn = "ppc_feasible_100hz_sensors"
    cfg = _config(scn, tmp_path / "cfg.bin")
    key = tmp_path / "key"
    key.write_bytes(b"the sanitizer bench's key")
    script = f"""
set -e
{ctl} --config {cfg} --mode realtime --trigger {trigger} --auth-key {key} --lcm-url '{url}' \\
    --summary {tmp_path}/sum1.json \\
    > /dev/null 2> {tmp_path}/ctl1.err &
CTL=$!
{_wait_for('mode on', tmp_path / 'ctl1.err')}
{PY} -m sc_rt.cli emulator {scn} --mode realtime --auth-key {key} --lcm-url '{url}' --duration 4 \\
    > {tmp_path}/emu1.log 2>&1
kill -TERM $CTL
wait $CTL
{ctl} --config {cfg} --mode realtime --trigger {trigger} --lcm-url '{url}' --summary {tmp_path}/sum2.json \\
    > /dev/null 2> {tmp_path}/ctl2.err &
CTL=$!
{_wait_for('mode on', tmp_path / 'ctl2.err')}
{PY} -m sc_rt.cli emulator {scn} --mode realtime --lcm-url '{url}' --duration 8 > {tmp_path}/emu2.log 2>&1 &
EMU=$!
SCRT_WAIT_PID=$EMU {PY} {HERE / 'fuzz_lcm.py'} '{url}' 20000 {tmp_path}/sent.json 5 \\
    SCRT_STATE,SCRT_GYRO,SCRT_STAR,SCRT_TACH
wait $EMU
kill -TERM $CTL
wait $CTL
"""
    _bench(script, tmp_path, TSAN_ENV)
    s1 = json.loads((tmp_path / "sum1.json").read_text())
    s2 = json.loads((tmp_path / "sum2.json").read_text())
    assert s1["mode"] == "realtime" and s1["auth"] and s1["steps"] >= 200 and s1["nav"]["gyro_used"] > 0, s1
    assert s2["steps"] >= 400 and s2["rejected"]["malformed"] > 0 and s2["nav"]["rejected"]["malformed"] > 0, s2
