"""Messages of layouts sc-rt no longer sends, turned into the current ones,
so that a log written before a layout changed still reads (docs/LOGS.md).

- ``controller_config_v1_t`` (before the law interface version 2, issue
  #26): the built-in laws' gains were fields of their own (``dsc_*``,
  ``neso_*``, ``pd_*``, ``rft_*``); now each law takes its own parameter
  table. ``upgrade`` moves the gains of the law the message names into its
  table, under the names that law reads (cpp/src/law_dsc.cpp, law_pd.cpp,
  law_rft.cpp); a plugin's table is kept as it was.
- ``controller_config_v2_t`` (before the magnetic control went on the
  bus, issue 43): no ``mag_*``, ``bdot_*``; ``upgrade`` copies every
  field and leaves magnetic control off (the controller then had none).
- ``controller_config_v3_t`` (before the magnetometer's samples went on the
  bus, issue 43): no ``nav_mag_*``; ``upgrade`` copies every field and
  leaves the magnetometer off (the controller then took the true field).
- ``controller_status_v1_t`` (before the law's telemetry went on the bus,
  issue #26): no ``x2d``, ``rho_hat``, ``n_telemetry``, ``telemetry``.
  ``decode_current`` reads such messages with the current ones, those
  fields NaN (``n_telemetry`` 0): not recorded, not zero.
- ``controller_status_v2_t`` (before its telemetry block was generated from
  the core's field table, issue 39): the same fields in another order and
  none of the fields added to the table since (the gyro calibration's);
  ``decode_current`` reads it the same way, the missing fields NaN.
- ``controller_status_v3_t`` (before the magnetic control's fields went on
  the bus, issue 43): read the same way, those fields NaN.
- ``plant_truth_v1_t`` (before the rods' truth went on the bus, issue 43):
  read the same way, ``rod_dipole_cmd``, ``rod_dipole`` and ``dipole_B``
  NaN, ``n_rods`` and ``rod_fault`` 0 (logs/rebuild.py then rebuilds the
  rods' commands from ``rod_cmd_t``).
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import sc_rt_lcm

from sc_rt.wire.codec import decode_array, numpy_dtype

__all__ = ["LEGACY", "upgrade", "decode_current"]

#: the old layout's class -> the current one it becomes
LEGACY = {sc_rt_lcm.controller_config_v1_t: sc_rt_lcm.controller_config_t,
          sc_rt_lcm.controller_config_v2_t: sc_rt_lcm.controller_config_t,
          sc_rt_lcm.controller_config_v3_t: sc_rt_lcm.controller_config_t,
          sc_rt_lcm.controller_status_v1_t: sc_rt_lcm.controller_status_t,
          sc_rt_lcm.controller_status_v2_t: sc_rt_lcm.controller_status_t,
          sc_rt_lcm.controller_status_v3_t: sc_rt_lcm.controller_status_t,
          sc_rt_lcm.plant_truth_v1_t: sc_rt_lcm.plant_truth_t}
#: a fixed-size current type -> its old layouts (read by decode_current; the others: upgrade)
_FIXED_OLD: dict[type, tuple[type, ...]] = {}
for _old, _new in LEGACY.items():
    if numpy_dtype(_new) is not None:
        _FIXED_OLD[_new] = _FIXED_OLD.get(_new, ()) + (_old,)


def decode_current(cls, datas: list[bytes], counts: Counter | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``codec.decode_array`` of a fixed-size type, messages of its old layout
    included: they become records of the current one (the fields they share
    copied, the others NaN, or 0 for an integer). Returns (records, index)
    in log order."""
    counts = Counter() if counts is None else counts
    olds = [o for o in _FIXED_OLD.get(cls, ())]
    fps = [o._get_packed_fingerprint() for o in olds]
    heads = [bytes(d[:8]) for d in datas]
    which = [fps.index(h) if h in fps else -1 for h in heads]
    if not any(w >= 0 for w in which):
        return decode_array(cls, datas, counts)
    at_new = np.flatnonzero(np.asarray(which) < 0)
    rec_new, i_new = decode_array(cls, [datas[i] for i in at_new], counts)
    parts, pos = [rec_new], [at_new[i_new]]
    for j, old in enumerate(olds):
        at_old = np.flatnonzero(np.asarray(which) == j)
        if not len(at_old):
            continue
        rec_old, i_old = decode_array(old, [datas[i] for i in at_old], counts)
        up = np.zeros(len(rec_old), rec_new.dtype)
        for name in up.dtype.names:
            if name in rec_old.dtype.names:
                up[name] = rec_old[name]
            elif up.dtype[name].base.kind == "f":
                up[name] = np.nan
        up["_fp"] = int.from_bytes(cls._get_packed_fingerprint(), "big")
        parts.append(up)
        pos.append(at_old[i_old])
    allpos = np.concatenate(pos)
    order = np.argsort(allpos, kind="stable")
    return np.concatenate(parts)[order], allpos[order].astype(np.int64)


_DSC = ("k1", "k2", "k3", "k4", "k6", "tau")
_NESO = ("k1", "k2", "k3", "k4")
_RFT = ("c", "k", "gain", "leak", "phi", "rho0")


def _law_table(m) -> list[tuple[str, list[float]]]:
    """The v1 message's gains of the law it names, as that law's table."""
    law = m.law
    if law in ("dsc-ppc", "dsc"):
        items = [(k, [float(getattr(m, "dsc_" + k))]) for k in _DSC]
        items += [("neso_" + k, [float(x) for x in getattr(m, "neso_" + k)]) for k in _NESO]
        items += [("neso_alpha", [float(m.neso_alpha)]), ("neso_substeps", [float(m.neso_substeps)]),
                  ("neso_init_from_measurement", [1.0 if m.neso_init_from_measurement else 0.0])]
        return items
    if law == "pd":
        return [("beta1", [float(m.pd_beta1)]), ("beta2", [float(m.pd_beta2)])]
    if law == "rft":
        return [(k, [float(getattr(m, "rft_" + k))]) for k in _RFT]
    return []


def _copy_shared(old, new):
    """``new`` with every field the two layouts share as in ``old`` (the others as
    the type makes them: off, zeros; a fixed array of the current layout's size)."""
    new_fields = set(new.__slots__)
    for name in old.__slots__:
        if name in new_fields:
            setattr(new, name, getattr(old, name))
    if not hasattr(old, "mag_G_B"):
        new.mag_G_B = [[0.0] * 6 for _ in range(3)]
        new.mag_dipole_max = [0.0] * 6
    new.nav_mag_R_SB = [[0.0] * 3 for _ in range(3)]
    return new


def upgrade(m):
    """A message of a legacy layout of a variable-size type as its current
    type (others unchanged; the fixed-size ones are read by decode_current)."""
    if isinstance(m, (sc_rt_lcm.controller_config_v2_t, sc_rt_lcm.controller_config_v3_t)):
        # every field as it was; no magnetic control (v2), no magnetometer samples (v2, v3)
        return _copy_shared(m, sc_rt_lcm.controller_config_t())
    if not isinstance(m, sc_rt_lcm.controller_config_v1_t):
        return m
    from sc_rt import _core

    new = _copy_shared(m, sc_rt_lcm.controller_config_t())
    # the plugin's own table (its [controller.params]) first, then the built-in law's gains
    table, at = [], 0
    for key, n in zip(m.law_param_keys, m.law_param_len):
        table.append((key, list(m.law_param_values[at:at + n])))
        at += n
    table += _law_table(m)
    new.law_api_version = _core.LAW_API_VERSION
    new.n_law_params = len(table)
    new.law_param_keys = [k for k, _ in table]
    new.law_param_len = [len(v) for _, v in table]
    new.law_param_values = [x for _, v in table for x in v]
    new.n_law_param_values = len(new.law_param_values)
    new.wheel_torque_command = False  # the paper's wheels: the only ones then
    new.wheel_speed_max = [0.0] * 4  # none (0 on the wire)
    return new
