"""The emulator's publishing side (a mixin of ``emulator.process.Emulator``):
the guidance and the state of a control instant, the truth of a row, the
sensors' samples of a plant step (emulator/sensorpub.py), and draining what our
own multicast brings back. Uses the emulator's ``lc``, ``session``,
``guidance``, ``inbox``, ``twin``, ``act``, ``sensors``, ``_bias_true``,
``_guidance_sent`` and channel names."""

from __future__ import annotations

import select
import time

import numpy as np

from sc_rt.emulator.twin import state_bytes, truth_bytes

__all__ = ["Publisher"]


class Publisher:
    def _publish_state(self, k: int, t: float, x: np.ndarray, guidance: tuple | None = None) -> None:
        if guidance is None:  # computed now, or the values state k went out with (a re-sent state)
            guidance = self._guidance_sent[1] if self._guidance_sent[0] == k else self.guidance.values(t)
        self._guidance_sent = (k, guidance)
        self.guidance.publish(k, t, guidance)  # the reference first: a controller has it with the state
        utime = time.time_ns() // 1000
        data = state_bytes(utime, k, self.session, t, x)
        self.inbox.published(k, utime, time.monotonic_ns())
        self.lc.publish(self._ch_state, data)
        self._drain()  # our own guidance and state come back (loopback): handled while the controller works

    def _sense(self, i: int, t: float, x: np.ndarray, row: int) -> None:
        """The sensors at plant step i (a control instant, row ``row``) when
        one is due; the gyro's true bias of the row either way."""
        if i == self.sensors.next_tick:
            self.sensors.tick(i, t, x)
        self._bias_true[row] = self.sensors.gyro_bias

    def _drain(self) -> None:
        """Handle what is already in the socket, without waiting."""
        fd = self.lc.fileno()
        while select.select([fd], [], [], 0)[0]:
            self.lc.handle()

    def _publish_truth(self, run, k, t, cmd_seq, u_cmd, accel, delta2, stale, act=None) -> None:
        act = self.act if act is None else act  # the faults row k was applied with
        fault_y, eff_bias_stuck = self.twin.fault_fields(act, t)
        bias = (0.0, 0.0, 0.0) if self._bias_true is None else self._bias_true[k]
        self.lc.publish(self._ch_truth, truth_bytes(time.time_ns() // 1000, k, t, cmd_seq, u_cmd, accel, delta2,
                                                    self.twin.disturbance(t), fault_y, eff_bias_stuck, stale,
                                                    bias))
        run["fault_Y"][k] = fault_y
        run["fault_effectiveness"][k] = eff_bias_stuck[0:4]
        run["fault_bias"][k] = eff_bias_stuck[4:8]
        run["fault_stuck"][k] = eff_bias_stuck[8:12]
