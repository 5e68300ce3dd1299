"""What the camera tracker looks for (bpy-free): a single ArUco marker or a ChArUco board, in the
world frame of design.md (origin at the target's centre, target in z = 0, +Z out of the printed
face, +X right and +Y up in the printed image). boards.py prints them."""
from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import PlateLightError

def get_dictionary(name: str):
    import cv2

    key = name.strip().upper()
    if not key.startswith("DICT_"):
        key = "DICT_" + key
    if not hasattr(cv2.aruco, key):
        raise PlateLightError(
            f"Unknown marker dictionary '{name}'; use one of OpenCV's, e.g. DICT_4X4_50 or DICT_6X6_250.")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, key))


@dataclasses.dataclass
class MarkerTarget:
    """One square ArUco marker of side ``size`` metres (any id, or ``marker_id``)."""
    dictionary: str
    size: float
    marker_id: int | None = None

    def __post_init__(self):
        if not (np.isfinite(self.size) and self.size > 0):
            raise PlateLightError(f"The marker size must be a positive length in metres, not {self.size}.")
        self.cv_dictionary = get_dictionary(self.dictionary)

    @property
    def extent(self) -> tuple[float, float]:
        return (self.size, self.size)

    def corner_points(self) -> np.ndarray:
        """Object points of the four corners in OpenCV's order (top-left, top-right,
        bottom-right, bottom-left), in the world frame; the order SOLVEPNP_IPPE_SQUARE wants."""
        h = self.size / 2.0
        return np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], dtype=np.float64)


@dataclasses.dataclass
class CharucoTarget:
    """A ChArUco board: ``squares`` (columns, rows), square and marker side in metres."""
    dictionary: str
    squares: tuple[int, int]
    square_size: float
    marker_size: float
    legacy: bool = False

    def __post_init__(self):
        import cv2

        if min(self.squares) < 2:
            raise PlateLightError("A ChArUco board needs at least 2 x 2 squares.")
        if not (0 < self.marker_size < self.square_size):
            raise PlateLightError("The ChArUco marker size must be positive and smaller than the square size.")
        self.cv_dictionary = get_dictionary(self.dictionary)
        self.board = cv2.aruco.CharucoBoard(tuple(int(v) for v in self.squares), float(self.square_size),
                                            float(self.marker_size), self.cv_dictionary)
        self.board.setLegacyPattern(bool(self.legacy))

    @property
    def size(self) -> float:
        return self.square_size

    @property
    def extent(self) -> tuple[float, float]:
        return (self.squares[0] * self.square_size, self.squares[1] * self.square_size)

    def board_to_world(self, points: np.ndarray) -> np.ndarray:
        """OpenCV's board frame (origin top-left, y down, z into the board) -> ours."""
        w, h = self.extent
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return np.stack([p[:, 0] - w / 2, h / 2 - p[:, 1], -p[:, 2]], axis=1)
