"""The emulator packs and unpacks its messages with struct for speed
(emulator/twin.py, emulator/inbox.py); the bytes must be exactly what the generated
LCM classes produce and read."""

from __future__ import annotations

import random

import sc_rt_lcm

from sc_rt.emulator import inbox as I
from sc_rt.emulator import twin as T


def test_state_and_truth_packing_equal_the_generated_encoding():
    rng = random.Random(5)
    for _ in range(200):
        m = sc_rt_lcm.plant_state_t()
        m.utime, m.seq, m.session = rng.getrandbits(50), rng.getrandbits(40), rng.getrandbits(62)
        m.t = rng.uniform(0, 1e4)
        x = [rng.uniform(-1e3, 1e3) for _ in range(10)]
        m.sigma_BN, m.omega_BN_B, m.wheel_speed = x[0:3], x[3:6], x[6:10]
        assert T._STATE_FP + T._STATE_LAYOUT.pack(m.utime, m.seq, m.session, m.t, *x) == m.encode()

        tr = sc_rt_lcm.plant_truth_t()
        tr.utime, tr.seq = rng.getrandbits(50), rng.getrandbits(40)
        tr.t, tr.cmd_seq_applied = rng.uniform(0, 1e4), rng.randrange(-1, 10**6)
        f = [[rng.uniform(-10, 10) for _ in range(n)] for n in (4, 4, 3, 3, 4, 4, 4)]
        tr.u_cmd, tr.wheel_accel, tr.delta2, tr.disturbance, tr.fault_Y, tr.fault_effectiveness, tr.fault_bias = f
        tr.fault_stuck = [rng.randrange(0, 2) for _ in range(4)]
        tr.cmd_stale = rng.randrange(0, 2)
        tr.gyro_bias = [rng.uniform(-1e-4, 1e-4) for _ in range(3)]
        tr.n_rods = rng.randrange(0, 7)
        tr.rod_dipole_cmd, tr.rod_dipole, tr.dipole_B = ([rng.uniform(-500, 500) for _ in range(n)]
                                                         for n in (6, 6, 3))
        tr.rod_fault = [rng.randrange(-3, 4) for _ in range(6)]
        rods = (tr.n_rods, tr.rod_dipole_cmd, tr.rod_dipole, tr.dipole_B, tr.rod_fault)
        tr.fault_seq_applied, tr.fault_seq_refused = rng.randrange(-1, 2**62), rng.randrange(-1, 2**62)
        packed = T._TRUTH_FP + T._TRUTH_LAYOUT.pack(tr.utime, tr.seq, tr.t, tr.cmd_seq_applied,
                                                    *[v for arr in f for v in arr], *tr.fault_stuck,
                                                    tr.cmd_stale, *tr.gyro_bias, tr.n_rods, *tr.rod_dipole_cmd,
                                                    *tr.rod_dipole, *tr.dipole_B, *tr.rod_fault,
                                                    tr.fault_seq_applied, tr.fault_seq_refused)
        assert packed == tr.encode()
        assert T.truth_bytes(tr.utime, tr.seq, tr.t, tr.cmd_seq_applied, *f[0:4], f[4], f[5] + f[6]
                             + tr.fault_stuck, tr.cmd_stale, tr.gyro_bias, rods,
                             (tr.fault_seq_applied, tr.fault_seq_refused)) == tr.encode()
        # a plant without rods: every rod field 0, as the generated class starts them
        tr.n_rods, tr.rod_fault = 0, [0] * 6
        tr.rod_dipole_cmd, tr.rod_dipole, tr.dipole_B = [0.0] * 6, [0.0] * 6, [0.0] * 3
        tr.fault_seq_applied = tr.fault_seq_refused = -1  # and no fault command yet
        assert T.truth_bytes(tr.utime, tr.seq, tr.t, tr.cmd_seq_applied, *f[0:4], f[4], f[5] + f[6]
                             + tr.fault_stuck, tr.cmd_stale, tr.gyro_bias) == tr.encode()


def test_command_and_status_unpacking_read_the_generated_encoding():
    rng = random.Random(6)
    for _ in range(200):
        c = sc_rt_lcm.wheel_cmd_t()
        c.utime, c.seq, c.session, c.state_seq = (rng.getrandbits(50), rng.getrandbits(40),
                                                   rng.getrandbits(62), rng.randrange(-1, 10**6))
        c.t = rng.uniform(0, 1e4)
        c.u_cmd = [rng.uniform(-1e6, 1e6) for _ in range(4)]
        c.u_sat = [rng.uniform(-10, 10) for _ in range(4)]
        c.mode, c.flags = rng.randrange(0, 3), rng.getrandbits(20)
        v = I._CMD_LAYOUT.unpack_from(c.encode(), 8)
        assert (v[1], v[2], v[3], list(v[5:9]), list(v[9:13])) == (c.seq, c.session, c.state_seq, c.u_cmd, c.u_sat)
        s = sc_rt_lcm.controller_status_t()
        s.utime, s.cmd_seq, s.session, s.state_seq = (rng.getrandbits(50), rng.getrandbits(40),
                                                      rng.getrandbits(62), rng.randrange(-1, 10**6))
        data = s.encode()
        assert len(data) == I._STATUS_SIZE and data[:8] == I._STATUS_FP
        assert I._STATUS_HEAD.unpack_from(data, 8) == (s.utime, s.cmd_seq, s.session, s.state_seq)
