"""Message authentication (--auth-key): SHA-256 and HMAC-SHA256 of the
controller (cpp/shell/hmac.hpp, through the binding) and of Python's hmac
module against FIPS 180-4 and RFC 4231; the trailer; a forger on the bus
that knows the protocol but not the key."""

from __future__ import annotations

import hashlib
import hmac
import json
import shlex
import sys
from collections import Counter
from pathlib import Path

import pytest

from sc_rt import _core
from sc_rt.wire.auth import TAG_SIZE, AuthLCM, message_tag, verified_payload
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

import lcmnet
from trajcmp import compared_fields, load_traj

ROOT = Path(__file__).resolve().parent.parent
HERE = Path(__file__).resolve().parent
PY = shlex.quote(sys.executable)

# RFC 4231, test cases 1-4, 6, 7 (5 is a truncated tag): key, data, HMAC-SHA256
RFC4231 = [
    (b"\x0b" * 20, b"Hi There", "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7"),
    (b"Jefe", b"what do ya want for nothing?",
     "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843"),
    (b"\xaa" * 20, b"\xdd" * 50, "773ea91e36800e46854db8ebd09181a72959098b3ef8c122d9635514ced565fe"),
    (bytes(range(1, 26)), b"\xcd" * 50, "82558a389a443c0ea4cc819899f2083a85f0faa3e578f8077a2e3ff46729665b"),
    (b"\xaa" * 131, b"Test Using Larger Than Block-Size Key - Hash Key First",
     "60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54"),
    (b"\xaa" * 131, b"This is a test using a larger than block-size key and a larger than block-size data. "
     b"The key needs to be hashed before being used by the HMAC algorithm.",
     "9b09ffa71b942fcb27635fbcd5b0e944bfdc63644f0713938a7f51535c3a35e2"),
]
# FIPS 180-4 examples (and the NIST one-million-'a' message)
SHA256 = [
    (b"abc", "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"),
    (b"abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq",
     "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1"),
    (b"", "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"),
    (b"a" * 1_000_000, "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0"),
]


@pytest.mark.parametrize("data,want", SHA256, ids=range(len(SHA256)))
def test_sha256_fips_vectors(data, want):
    assert _core.sha256(data).hex() == want == hashlib.sha256(data).hexdigest()


@pytest.mark.parametrize("key,data,want", RFC4231, ids=[1, 2, 3, 4, 6, 7])
def test_hmac_sha256_rfc4231_vectors_in_cpp_and_python(key, data, want):
    assert _core.hmac_sha256(key, data).hex() == want
    assert hmac.new(key, data, hashlib.sha256).hexdigest() == want


def test_every_length_around_the_block_agrees():
    # the padding's edge cases: 55, 56, 63, 64, 65 bytes and two blocks
    for n in range(0, 200):
        data = bytes((i * 7 + n) & 0xFF for i in range(n))
        assert _core.sha256(data) == hashlib.sha256(data).digest(), n
        assert _core.hmac_sha256(b"k" * (n % 80 + 1), data) == hmac.new(b"k" * (n % 80 + 1), data,
                                                                         hashlib.sha256).digest(), n


def test_trailer_is_the_same_in_both_processes_and_binds_the_channel():
    key, payload = b"lab key", bytes(range(100))
    t = message_tag(key, "SCRT_CMD", payload)
    assert len(t) == TAG_SIZE and _core.message_tag(key, "SCRT_CMD", payload) == t
    assert verified_payload(key, "SCRT_CMD", payload + t) == payload
    assert verified_payload(key, "P_SCRT_CMD", payload + t) is None  # moved to another channel
    assert verified_payload(b"other", "SCRT_CMD", payload + t) is None
    flipped = bytearray(payload + t)
    flipped[3] ^= 1
    assert verified_payload(key, "SCRT_CMD", bytes(flipped)) is None
    assert verified_payload(key, "SCRT_CMD", t[:10]) is None


def test_auth_lcm_tags_what_it_sends_and_drops_what_does_not_verify():
    class Fake:
        def __init__(self):
            self.sent, self.handlers = [], {}

        def publish(self, ch, data):
            self.sent.append((ch, data))

        def subscribe(self, ch, h):
            self.handlers[ch] = h
            return "sub"

    fake, got, c = Fake(), [], Counter()
    a = AuthLCM(fake, b"k", c)
    a.publish("SCRT_STATE", b"xyz")
    assert fake.sent == [("SCRT_STATE", b"xyz" + message_tag(b"k", "SCRT_STATE", b"xyz"))]
    assert a.subscribe("SCRT_CMD", lambda ch, d: got.append(d)) == "sub"
    h = fake.handlers["SCRT_CMD"]
    h("SCRT_CMD", b"abc" + message_tag(b"k", "SCRT_CMD", b"abc"))
    h("SCRT_CMD", b"abc")  # no tag
    h("SCRT_CMD", b"abc" + message_tag(b"k", "SCRT_STATE", b"abc"))  # another channel's tag
    assert got == [b"abc"] and c["auth_failed"] == 2


@pytest.mark.lcm
@pytest.mark.slow  # ~6-10 s: a lockstep run under a forger
def test_forger_without_the_key_changes_nothing(tmp_path):
    lcmnet.require()
    url = "udpm://239.255.76.67:7722?ttl=0&recv_buf_size=4194304"
    key = tmp_path / "lab.key"
    key.write_bytes(b"a bench's shared key, 32+ bytes long......")
    out = tmp_path / "hil"
    script = f"""
{PY} -m sc_rt.cli hil scenarios/paper_faults.toml --duration 300 --no-plots --out {out} \\
    --lcm-url '{url}' --auth-key {key} > {tmp_path}/hil.log 2>&1 &
HIL=$!
SCRT_WAIT_PID=$HIL {PY} {HERE / 'forge_lcm.py'} '{url}' {tmp_path}/forged.json
wait $HIL
"""
    r = lcmnet.run_script(script, timeout=300)
    assert r.returncode == 0, r.stderr + (tmp_path / "hil.log").read_text()
    forged = json.loads((tmp_path / "forged.json").read_text())
    timing = json.loads((out / "timing.json").read_text())
    summary = json.loads((out / "controller_summary.json").read_text())
    emu = timing["emulator_counters"]
    assert forged["heard"] > 100, forged  # the forger ran during the run
    # every forged message that reached a process failed its check and was
    # counted there; none was applied: the run is the offline run to the bit
    assert 0 < emu["auth_failed"], emu
    assert summary["auth"] is True and 0 < summary["auth_failed"] <= forged["sent"]["SCRT_STATE"], summary
    assert "foreign_session" not in emu and summary["rejected"]["foreign_session"] == 0
    assert summary["sessions_adopted"] == 0 and "controller_sessions_adopted" not in emu
    hil = load_traj(out)
    sim = simulate(load_scenario(ROOT / "scenarios/paper_faults.toml"), engine="python", duration=300)
    compared_fields(hil, sim)
    m = json.loads((out / "metrics.json").read_text())
    assert m["valid"] is True and m["controller_session"] is not None
