"""Colours, sizes and file names of the figures, and how one is saved."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

RESOLUTION = 120  # grid points per axis of a slice
HIDDEN_SAMPLES = 27  # failure figures: samples of the coordinates a plane hides (in all)
SURFACE_GRID, SURFACE_DEPTH = 40, 141  # (x, y) grid and z samples of a 3-D boundary
# the camera stands at the corner of low x and high y: a boundary that rises toward high x
# and low y (lead-follow: fast follower, slow lead; fleet3's lead side) shows its whole slope
# instead of hiding behind the flat part (looked at on lead-follow and both fleet3 sides)
VIEW_ELEVATION, VIEW_AZIMUTH = 28, 135
LEVELS = 4  # slices per Slices hint (values of the varied coordinate, ends included)
# Okabe-Ito blue and vermillion: told apart with every common colour-vision deficiency
# (blue against a red-brown, and by lightness), neither near white
SAFE_COLOUR = "#0072B2"
PRUNED_COLOUR = "#D55E00"
NEVER_COLOUR, NEVER_HATCH, NEVER_HATCH_COLOUR = "#e4e4e4", "////", "#a6a6a6"  # light grey, hatched
OUTSIDE_COLOUR = "#f4c9c4"  # "not in the safe set" when there is no exploration record
OVERLAY_COLOURS = ("#1f5fbf", "#e8710a", "#7b3fb5", "#1a9e8f", "#c2185b", "#6d5d00")
SLICES_FILE, SURFACE_FILE, PROJECTIONS_FILE = "safe_set_slices.png", "safe_set_3d.png", "safe_set_projections.png"


def _save(fig, path: Path, dpi=100) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fig.savefig(path, dpi=dpi)
    finally:
        plt.close(fig)
    return path
