"""gyro_calibration.png: the calibrating filter's gyro scale factors and
misalignments (the record's ``gyro_cal_est``) with their 3 sigma
(``gyro_cal_3sigma``), and the gyro's true values when the run knows them
(the scenario's ``[sensors.gyro]``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sc_rt.results.present.figure_marks import mark_events, run_title
from sc_rt.results.present.figures import save_figure
from sc_rt.results.record.run import Run

__all__ = ["calibration_figure", "CAL_NAMES"]

#: The nine values of ``gyro_cal_est`` in order: S = [[s1 ku1 ku2], [kl1 s2 ku3], [kl2 kl3 s3]]
CAL_NAMES = ("s1", "s2", "s3", "ku1", "ku2", "ku3", "kl1", "kl2", "kl3")
_PPM = 1e-6
_ARCSEC = math.pi / 180.0 / 3600.0


def calibration_figure(run: Run, out: Path, title: str = "", truth: np.ndarray | None = None) -> Path | None:
    """gyro_calibration.png: two panels, the scale factors [ppm] and the six
    misalignments [arcsec], each estimate with its +-3 sigma band (dotted)
    and, given ``truth`` (the nine true values [-, rad]), the truth dashed.
    None when the run has no calibrating filter (its estimates NaN)."""
    import matplotlib.pyplot as plt

    est = np.asarray(run["gyro_cal_est"], float)
    if not np.isfinite(est).any():
        return None
    sd3 = np.asarray(run["gyro_cal_3sigma"], float)
    t = np.asarray(run["t"], float)
    fig, axs = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    for ax, idx, scale, unit in ((axs[0], range(3), _PPM, "ppm"), (axs[1], range(3, 9), _ARCSEC, "arcsec")):
        for j in idx:
            line, = ax.plot(t, est[:, j] / scale, lw=0.9, label=CAL_NAMES[j])
            c = line.get_color()
            ax.plot(t, (est[:, j] + sd3[:, j]) / scale, ":", lw=0.7, color=c)
            ax.plot(t, (est[:, j] - sd3[:, j]) / scale, ":", lw=0.7, color=c)
            if truth is not None:
                ax.axhline(truth[j] / scale, ls="--", lw=0.7, color=c)
        ax.set_ylabel(f"[{unit}]")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8, ncol=3)
        mark_events(ax, run)
    axs[0].set_title("Gyro calibration estimate (dotted: +-3 sigma; dashed: the truth)\n"
                     f"{title or run_title(run)}", fontsize=10)
    axs[1].set_xlabel("t [s]")
    return save_figure(fig, Path(out) / "gyro_calibration.png")
