"""The sample of a scan: a background surface with features painted over it, and the
raster of pixel centres it is sampled on.

Geometry (all SI, metres): the scan area is ``[0, size_x] x [0, size_y]`` with x the
fast axis; pixel ``(ix, iy)`` has its centre at ``((ix + 1/2) size_x/nx, (iy + 1/2)
size_y/ny)`` and takes the material and height of whatever covers that centre.
Features are painted over the background in the order written, so a later feature
covers an earlier one:

* ``disk``: ``(x - cx)^2 + (y - cy)^2 <= r^2``;
* ``rectangle``: ``x0 <= x < x0 + w`` and ``y0 <= y < y0 + h`` (half-open, so two
  rectangles that share an edge never both claim a pixel).

A *domain* is the background (0) or a feature (its 1-based position in the list);
a *material* is a distinct surface section: features with equal surfaces share one
material (and one kernel per line).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

SHAPES = ("disk", "rectangle")


@dataclass(frozen=True)
class Feature:
    """One feature of the sample: its shape, the height of its top [m] and its surface
    section (the background's keys completed by the feature's own)."""

    shape: str  # disk | rectangle
    height: float  # [m] height of the feature's top above the scan's zero
    surface: dict  # resolved surface section (model keys + common keys)
    center: tuple = (math.nan, math.nan)  # disk: (cx, cy) [m]
    radius: float = math.nan  # disk [m]
    corner: tuple = (math.nan, math.nan)  # rectangle: (x0, y0) [m]
    size: tuple = (math.nan, math.nan)  # rectangle: (w, h) [m]

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Which of the points ``(x, y)`` [m] the feature covers (module docstring)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        if self.shape == "disk":
            return (x - self.center[0]) ** 2 + (y - self.center[1]) ** 2 <= self.radius**2
        x0, y0 = self.corner
        w, h = self.size
        return (x >= x0) & (x < x0 + w) & (y >= y0) & (y < y0 + h)

    def bounds(self) -> tuple[float, float, float, float]:
        """``(x0, y0, x1, y1)`` [m]: the feature's bounding box."""
        if self.shape == "disk":
            (cx, cy), r = self.center, self.radius
            return cx - r, cy - r, cx + r, cy + r
        (x0, y0), (w, h) = self.corner, self.size
        return x0, y0, x0 + w, y0 + h

    def outline(self, n: int = 181) -> tuple[np.ndarray, np.ndarray]:
        """A closed polygon of the feature's boundary [m] (for the figures' domain outlines)."""
        if self.shape == "disk":
            a = np.linspace(0.0, 2.0 * math.pi, n)
            return self.center[0] + self.radius * np.cos(a), self.center[1] + self.radius * np.sin(a)
        x0, y0 = self.corner
        w, h = self.size
        return np.array([x0, x0 + w, x0 + w, x0, x0]), np.array([y0, y0, y0 + h, y0 + h, y0])

    def describe(self) -> str:
        if self.shape == "disk":
            return f"disk r = {self.radius * 1e9:.4g} nm at ({self.center[0] * 1e9:.4g}, {self.center[1] * 1e9:.4g}) nm"
        return (f"rectangle {self.size[0] * 1e9:.4g} x {self.size[1] * 1e9:.4g} nm at "
                f"({self.corner[0] * 1e9:.4g}, {self.corner[1] * 1e9:.4g}) nm")  # fmt: skip

    def to_dict(self) -> dict:
        d = {"shape": self.shape}
        if self.shape == "disk":
            d.update(center=list(self.center), radius=self.radius)
        else:
            d.update(corner=list(self.corner), size=list(self.size))
        d.update(height=self.height, surface=dict(self.surface))
        return d


def feature_from_dict(d: dict) -> Feature:
    """A :class:`Feature` from its :meth:`Feature.to_dict` (a table's metadata)."""
    kw = {k: tuple(d[k]) for k in ("center", "corner", "size") if k in d}
    if "radius" in d:
        kw["radius"] = float(d["radius"])
    return Feature(d["shape"], float(d["height"]), dict(d.get("surface") or {}), **kw)


@dataclass(frozen=True)
class Sample:
    """Background surface and height, and the features painted over it in order."""

    background: dict  # resolved surface section of the background
    height: float  # [m] background height
    features: tuple = ()  # of Feature

    def domain_names(self) -> list[str]:
        """Name of every domain: 'background', then 'feature k (shape)'."""
        return ["background"] + [f"feature {i + 1} ({f.shape})" for i, f in enumerate(self.features)]

    def surfaces(self) -> list[dict]:
        """Surface section of every domain (background first)."""
        return [self.background] + [f.surface for f in self.features]

    def heights(self) -> list[float]:
        return [self.height] + [f.height for f in self.features]


@dataclass(frozen=True)
class Raster:
    """The pixel grid: ``nx`` pixels along the fast axis x, ``ny`` lines along y."""

    nx: int
    ny: int
    size_x: float  # [m]
    size_y: float  # [m]

    @property
    def pitch(self) -> tuple[float, float]:
        """Pixel spacing ``(size_x/nx, size_y/ny)`` [m]."""
        return self.size_x / self.nx, self.size_y / self.ny

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Pixel centres ``x[ix]``, ``y[iy]`` [m] (module docstring)."""
        px, py = self.pitch
        return (np.arange(self.nx) + 0.5) * px, (np.arange(self.ny) + 0.5) * py


@dataclass
class SampleMap:
    """The sample sampled on the raster: per pixel its domain, material and true height."""

    raster: Raster
    domain: np.ndarray  # (ny, nx) int: 0 background, k feature k
    material: np.ndarray  # (ny, nx) int: index into materials
    height: np.ndarray  # (ny, nx) [m] true height of the pixel's surface
    materials: list = field(default_factory=list)  # distinct surface sections
    covered: list = field(default_factory=list)  # pixels each domain holds (background first)

    def line(self, iy: int) -> list[tuple[int, float]]:
        """``(material index, height)`` of every pixel of line ``iy``, along x."""
        return [(int(m), float(h)) for m, h in zip(self.material[iy], self.height[iy])]


def surface_key(surface: dict) -> str:
    """A surface section as a canonical string (equal sections share a material)."""
    return json.dumps(surface, sort_keys=True)


def paint(sample: Sample, raster: Raster) -> SampleMap:
    """Domain, material and true height of every pixel (module docstring)."""
    x, y = raster.centres()
    xx, yy = np.meshgrid(x, y)
    domain = np.zeros((raster.ny, raster.nx), dtype=np.int64)
    for i, f in enumerate(sample.features):
        domain[f.contains(xx, yy)] = i + 1
    keys: dict[str, int] = {}
    materials: list[dict] = []
    of_domain = []
    for surf in sample.surfaces():
        k = surface_key(surf)
        if k not in keys:
            keys[k] = len(materials)
            materials.append(surf)
        of_domain.append(keys[k])
    material = np.asarray(of_domain, dtype=np.int64)[domain]
    height = np.asarray(sample.heights(), dtype=float)[domain]
    covered = [int(np.sum(domain == i)) for i in range(len(sample.features) + 1)]
    return SampleMap(raster, domain, material, height, materials, covered)
