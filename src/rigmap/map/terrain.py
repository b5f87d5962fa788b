"""Terrain under edited locomotion: height (cm, +Y) over the ground plane (X, Z), rig axes.

A terrain is procedural, named in config (:func:`procedural`: ``flat``, ``slope``,
``sine``), or a height field read from a file (:func:`read_height_field`): an ``.npz``
with ``heights`` (rows along Z, columns along X), ``cell_cm`` and optionally
``origin_cm`` (X, Z of ``heights[0, 0]``), or an ``.npy`` grid with the cell size given
apart. Between grid points the height is bilinear; outside the grid it is the nearest
edge's. The shapes' parameters are ours (the paper names no terrain).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigmap.errors import RigmapError

NAMES = ("flat", "slope", "sine")
SLOPE_PERCENT = 10.0  # ours: rise per 100 cm along the slope's heading
SINE_AMPLITUDE_CM = 6.0  # ours, as the map_partial demo's terrain
SINE_WAVELENGTH_CM = 120.0


class TerrainError(RigmapError, ValueError):
    """A terrain name, parameter or height-field file that cannot be used."""


@dataclass(frozen=True)
class Procedural:
    """``flat`` (0), ``slope`` (rising ``slope_percent`` % toward ``heading_deg``, 0 = +Z,
    90 = +X) or ``sine`` (``amplitude_cm · sin(2πx/λ) · cos(2πz/λ)``)."""

    name: str
    slope_percent: float = SLOPE_PERCENT
    heading_deg: float = 0.0
    amplitude_cm: float = SINE_AMPLITUDE_CM
    wavelength_cm: float = SINE_WAVELENGTH_CM

    def __post_init__(self) -> None:
        if self.name not in NAMES:
            raise TerrainError(f"terrain {self.name!r}: expected a file or one of {NAMES}")
        values = (self.slope_percent, self.heading_deg, self.amplitude_cm, self.wavelength_cm)
        if not all(np.isfinite(float(v)) for v in values) or not self.wavelength_cm > 0:
            raise TerrainError(f"terrain {self.name}: parameters {values} must be finite, λ > 0")

    def height(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        x, z = np.asarray(x, dtype=np.float64), np.asarray(z, dtype=np.float64)
        if self.name == "slope":
            heading = np.radians(self.heading_deg)
            along = x * np.sin(heading) + z * np.cos(heading)
            return self.slope_percent / 100.0 * along
        if self.name == "sine":
            k = 2 * np.pi / self.wavelength_cm
            return self.amplitude_cm * np.sin(k * x) * np.cos(k * z)
        return np.zeros(np.broadcast(x, z).shape)

    def describe(self) -> dict:
        return {"terrain": self.name, **_parameters(self)}


def _parameters(shape: Procedural) -> dict:
    if shape.name == "slope":
        return {"slope_percent": shape.slope_percent, "heading_deg": shape.heading_deg}
    if shape.name == "sine":
        return {"amplitude_cm": shape.amplitude_cm, "wavelength_cm": shape.wavelength_cm}
    return {}


@dataclass(frozen=True)
class HeightField:
    """A grid of heights (cm): ``heights[i, j]`` at X = origin X + j·cell, Z = origin Z + i·cell."""

    heights: np.ndarray
    cell_cm: float
    origin_cm: tuple[float, float] = (0.0, 0.0)
    source: str = ""

    def height(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        from scipy.interpolate import RegularGridInterpolator

        rows, cols = self.heights.shape
        zs = self.origin_cm[1] + self.cell_cm * np.arange(rows)
        xs = self.origin_cm[0] + self.cell_cm * np.arange(cols)
        x, z = np.broadcast_arrays(np.asarray(x, float), np.asarray(z, float))
        inside = np.stack([np.clip(z, zs[0], zs[-1]), np.clip(x, xs[0], xs[-1])], axis=-1)
        return RegularGridInterpolator((zs, xs), self.heights)(inside)

    def describe(self) -> dict:
        return {
            "terrain": self.source,
            "grid": list(self.heights.shape),
            "cell_cm": self.cell_cm,
            "origin_cm": list(self.origin_cm),
        }


def read_height_field(path: str | Path, cell_cm: float | None = None) -> HeightField:
    """A height field from ``.npz`` (``heights``, ``cell_cm``, ``origin_cm``) or ``.npy``
    (``cell_cm`` given); every fault is a one-line :class:`TerrainError` naming the file."""
    path = Path(path)
    if not path.is_file():
        raise TerrainError(f"terrain file {path} does not exist")
    origin = (0.0, 0.0)
    try:
        if path.suffix.lower() == ".npz":
            with np.load(path, allow_pickle=False) as data:
                if "heights" not in data:
                    raise TerrainError(f"terrain file {path}: no 'heights' array")
                heights = np.asarray(data["heights"], dtype=np.float64)
                cell_cm = float(data["cell_cm"]) if "cell_cm" in data else cell_cm
                if "origin_cm" in data:
                    origin = tuple(float(v) for v in np.ravel(data["origin_cm"]))
        elif path.suffix.lower() == ".npy":
            heights = np.asarray(np.load(path, allow_pickle=False), dtype=np.float64)
        else:
            raise TerrainError(f"terrain file {path}: expected .npz or .npy")
    except (OSError, ValueError, TypeError) as error:
        if isinstance(error, TerrainError):
            raise
        raise TerrainError(f"terrain file {path}: unreadable ({error})".splitlines()[0]) from None
    return _checked(heights, cell_cm, origin, path)


def _checked(heights, cell_cm, origin, path: Path) -> HeightField:
    if heights.ndim != 2 or min(heights.shape) < 2:
        raise TerrainError(f"terrain file {path}: heights of shape {heights.shape}, expected 2-D")
    if not np.isfinite(heights).all():
        raise TerrainError(f"terrain file {path}: heights hold NaN or infinite values")
    if cell_cm is None or not (np.isfinite(cell_cm) and cell_cm > 0):
        raise TerrainError(f"terrain file {path}: cell size {cell_cm!r} cm, expected a number > 0")
    if len(origin) != 2 or not np.isfinite(origin).all():
        raise TerrainError(f"terrain file {path}: origin_cm {origin!r}, expected [x, z]")
    return HeightField(heights, float(cell_cm), (float(origin[0]), float(origin[1])), str(path))
