"""`Cuboids`: N boxes as arrays in one named frame, the one box type of the package (numpy only).

Ground truth, predictions, tracks and projections are the same cuboids with other columns beside them (av2's
`CuboidList`, Waymo v2's `Box3d`, py123d's `BoxDetectionSE3` are the models): a class that carries cuboids and
per-box columns derives from `CuboidRows`, which gives it `len`, `take` and the box fields.

```python
@dataclass(frozen=True)
class Detections(CuboidRows):
    cuboids: Cuboids
    score: np.ndarray          # (N,)

detections.take(detections.score > 0.5).cuboids.corners()    # (M, 8, 3) in detections.cuboids.at
```
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from nuparquet.geometry.boxes import box_corners
from nuparquet.geometry.quaternions import as_float_array, multiply_quaternions, rotation_matrices

Frame = Literal["sensor", "ego", "global"]
FRAMES: tuple[Frame, ...] = ("sensor", "ego", "global")


@dataclass(frozen=True)
class Cuboids:
    """N boxes in the frame `at`.

    Attributes:
        translation_m: (N, 3) float64 box centres, metres.
        size_wlh_m: (N, 3) float64 [width, length, height] (the devkit's `wlh`), metres.
        rotation_wxyz: (N, 4) float64 orientations, quaternions [w, x, y, z] (not renormalised here).
        at: the frame the centres and orientations are in: "sensor", "ego" or "global".
    """

    translation_m: np.ndarray
    size_wlh_m: np.ndarray
    rotation_wxyz: np.ndarray
    at: Frame = "global"

    def __post_init__(self) -> None:
        if self.at not in FRAMES:
            raise ValueError(f"at must be one of {', '.join(FRAMES)}, not {self.at!r}")
        n = len(self.translation_m)
        if len(self.size_wlh_m) != n or len(self.rotation_wxyz) != n:
            raise ValueError(f"cuboid fields of different lengths: {n}, {len(self.size_wlh_m)}, "
                             f"{len(self.rotation_wxyz)}")

    @classmethod
    def of(cls, translation_m, size_wlh_m, rotation_wxyz, at: Frame = "global") -> Cuboids:
        """Cuboids from array-likes, checked for shape and made float64."""
        return cls(as_float_array(translation_m, (3,), "translation_m").reshape(-1, 3),
                   as_float_array(size_wlh_m, (3,), "size_wlh_m").reshape(-1, 3),
                   as_float_array(rotation_wxyz, (4,), "rotation_wxyz").reshape(-1, 4), at)

    @classmethod
    def empty(cls, at: Frame = "global") -> Cuboids:
        return cls(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 4)), at)

    @classmethod
    def concat(cls, parts: list[Cuboids], at: Frame | None = None) -> Cuboids:
        """One Cuboids of `parts` in order (all in one frame; `at` names it when `parts` may be empty)."""
        frames = {part.at for part in parts}
        if len(frames) > 1:
            raise ValueError(f"cuboids in different frames: {sorted(frames)}")
        at = frames.pop() if frames else (at or "global")
        if not parts:
            return cls.empty(at)
        return cls(np.concatenate([p.translation_m for p in parts]), np.concatenate([p.size_wlh_m for p in parts]),
                   np.concatenate([p.rotation_wxyz for p in parts]), at)

    def __len__(self) -> int:
        return len(self.translation_m)

    def take(self, rows) -> Cuboids:
        """The cuboids at `rows` (indices or a boolean mask), in that order."""
        return Cuboids(self.translation_m[rows], self.size_wlh_m[rows], self.rotation_wxyz[rows], self.at)

    def corners(self) -> np.ndarray:
        """(N, 8, 3) corners in `at`, in the devkit's `Box.corners()` order (front face first)."""
        return box_corners(self.translation_m, self.size_wlh_m, self.rotation_wxyz)

    def moved(self, X_from_at_translation_m, X_from_at_rotation_wxyz, at: Frame) -> Cuboids:
        """The cuboids in frame `at`, given the pose of their current frame in it (per box (N, 3)/(N, 4) or one
        (3,)/(4,)): centres rotated then translated, orientations composed, as the devkit's `Box.rotate` then
        `Box.translate` (the inverse direction is the caller's: pass the inverted pose)."""
        rotation = np.asarray(X_from_at_rotation_wxyz, dtype=np.float64)
        matrices = rotation_matrices(rotation)
        if matrices.ndim == 2:
            centres = self.translation_m @ matrices.T
        else:
            centres = np.einsum("nij,nj->ni", matrices, self.translation_m)
        translation = centres + np.asarray(X_from_at_translation_m, dtype=np.float64)
        orientation = multiply_quaternions(np.broadcast_to(rotation, self.rotation_wxyz.shape), self.rotation_wxyz)
        return Cuboids(translation, self.size_wlh_m, orientation, at)


@dataclass(frozen=True)
class CuboidRows:
    """Base of a dataclass that holds `cuboids: Cuboids` and per-box columns: (N, ...) arrays aligned with them.

    Gives `len`, `take(rows)` (the cuboids, every array field and every dict of arrays at `rows`; the fields named
    in `unaligned` and the other values kept as they are) and the box fields (`translation_m`, `size_wlh_m`,
    `rotation_wxyz`) read through to the cuboids."""

    unaligned: ClassVar[tuple[str, ...]] = ()  # array fields that are not one value per box (kept by `take`)

    cuboids: Cuboids

    def __len__(self) -> int:
        return len(self.cuboids)

    def take(self, rows):
        def taken(value):
            if isinstance(value, Cuboids):
                return value.take(rows)
            if isinstance(value, np.ndarray):
                return value[rows]
            if isinstance(value, dict) and all(isinstance(v, np.ndarray) for v in value.values()):
                return {key: v[rows] for key, v in value.items()}
            return value
        return dataclasses.replace(self, **{f.name: taken(getattr(self, f.name)) for f in dataclasses.fields(self)
                                            if f.init and f.name not in self.unaligned})

    @property
    def translation_m(self) -> np.ndarray:
        return self.cuboids.translation_m

    @property
    def size_wlh_m(self) -> np.ndarray:
        return self.cuboids.size_wlh_m

    @property
    def rotation_wxyz(self) -> np.ndarray:
        return self.cuboids.rotation_wxyz
