"""sc-rt-controller --config-channel --auth-key: the configuration on
SCRT_CONFIG is taken only with a tag that verifies (docs/PROTOCOL.md, 9)."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import pytest

import lcmnet

ROOT = Path(__file__).resolve().parent.parent
PY = shlex.quote(sys.executable)
pytestmark = pytest.mark.lcm

PUBLISH = """
import sys, time, lcm
from sc_rt.wire.auth import message_tag
url, cfg, key, mode = sys.argv[1:5]
data = open(cfg, 'rb').read()
lc = lcm.LCM(url)
if mode == 'untagged':
    out = data
elif mode == 'wrong':
    out = data + message_tag(b'another key', 'SCRT_CONFIG', data)
else:
    out = data + message_tag(open(key, 'rb').read(), 'SCRT_CONFIG', data)
for _ in range(10):
    lc.publish('SCRT_CONFIG', out)
    time.sleep(0.05)
"""


def test_config_channel_takes_only_a_verified_configuration(tmp_path):
    lcmnet.require()
    import subprocess

    cfg = tmp_path / "cfg.bin"
    subprocess.run([sys.executable, "-m", "sc_rt.cli", "config", "scenarios/paper_faults.toml", "--out", str(cfg)],
                   check=True, capture_output=True, cwd=ROOT)
    key = tmp_path / "k"
    key.write_bytes(b"the bench's key")
    pub = tmp_path / "pub.py"
    pub.write_text(PUBLISH)
    exe = shlex.quote(str(Path(sys.executable).parent / "sc-rt-controller"))
    url = "udpm://239.255.76.67:7724?ttl=0"
    # untagged and wrongly tagged configurations first: the controller keeps
    # waiting (it would print "mode on" once configured); then the tagged one
    script = f"""
{exe} --config-channel --auth-key {key} --lcm-url '{url}' --max-steps 1 > /dev/null 2> {tmp_path}/ctl.err &
C=$!
for i in $(seq 100); do grep -q 'waiting for' {tmp_path}/ctl.err && break; sleep 0.05; done
{PY} {pub} '{url}' {cfg} {key} untagged
{PY} {pub} '{url}' {cfg} {key} wrong
grep -q 'mode on' {tmp_path}/ctl.err && echo EARLY
{PY} {pub} '{url}' {cfg} {key} tagged
for i in $(seq 200); do grep -q 'mode on' {tmp_path}/ctl.err && break; sleep 0.05; done
kill -TERM $C; wait $C
"""
    r = lcmnet.run_script(script, timeout=60)
    err = (tmp_path / "ctl.err").read_text()
    assert "EARLY" not in r.stdout, err
    assert "mode on" in err, (r.stdout, err)
