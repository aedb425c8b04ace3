"""Checks that a figure has content (not its file size): the PNG is a drawn
plot, and the matplotlib Figure behind it can be inspected.

The figure functions write PNGs and return their paths, so
``record_figures`` keeps every Figure saved while a test runs, by name."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

# matplotlib's first colour cycle entry ("C0"): the first series of every figure
C0 = np.array([0x1F, 0x77, 0xB4]) / 255.0


def record_figures(monkeypatch) -> dict:
    """{file name: Figure} of every figure saved from now on (still saved)."""
    import matplotlib.figure

    saved: dict = {}
    original = matplotlib.figure.Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        name = Path(str(fname)).name
        # a figure is written whole under a temporary name, then renamed (jsonsafe.atomic_path): its file's name
        part = re.fullmatch(r"\.(.+)\.\d+\.part", name)
        saved[part.group(1) if part else name] = self
        return original(self, fname, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", savefig)
    return saved


def assert_png_is_a_plot(path: Path, *, min_size: int = 200) -> None:
    """A readable PNG of a real plot: large enough, not one flat colour, some
    ink but not all ink (axes, text, lines), and a data series drawn in C0."""
    import matplotlib.image

    img = matplotlib.image.imread(str(path))
    assert img.ndim == 3 and img.shape[0] >= min_size and img.shape[1] >= min_size, (path, img.shape)
    rgb = img[..., :3].astype(float)
    if rgb.max() > 1.0:  # 8-bit
        rgb /= 255.0
    ink = np.any(rgb < 0.95, axis=-1)
    assert 0.005 < ink.mean() < 0.9, (path, ink.mean())
    colours = np.unique((rgb * 255).round().astype(np.uint8).reshape(-1, 3), axis=0)
    assert len(colours) > 20, (path, len(colours))
    series = np.all(np.abs(rgb - C0) < 0.05, axis=-1)
    assert series.sum() >= 50, (path, "no C0 series drawn", int(series.sum()))
