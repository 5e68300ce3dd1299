"""Frame ranges: parse ``10-20`` / ``7`` / ``1-3,8``, and split a range across machines."""
from __future__ import annotations

import numpy as np

from ..errors import PlateLightError


def parse_frames(text: str) -> list[int]:
    """Frames named by ``text`` (comma-separated frames or inclusive ranges), sorted, unique."""
    frames: set[int] = set()
    for part in str(text).replace(" ", "").split(","):
        if not part:
            continue
        try:
            if "-" in part[1:]:
                cut = part.index("-", 1)            # allow a negative first frame: -5-3
                start, end = int(part[:cut]), int(part[cut + 1:])
            else:
                start = end = int(part)
        except ValueError:
            raise PlateLightError(
                f"Cannot read the frame range {text!r}; write it like 10-20 or 1,5,9-12.") from None
        if end < start:
            raise PlateLightError(f"The frame range {part} ends before it starts.")
        if end - start > 100_000:
            raise PlateLightError(f"The frame range {part} is longer than 100000 frames.")
        frames.update(range(start, end + 1))
    if not frames:
        raise PlateLightError(f"The frame range {text!r} names no frames.")
    return sorted(frames)


def split_frames(frames: list[int], part: int, parts: int) -> list[int]:
    """The ``part``-th (1-based) of ``parts`` contiguous, near-equal chunks of ``frames``, so
    that N machines given 1/N ... N/N bake every frame exactly once."""
    if not 1 <= part <= parts:
        raise PlateLightError(f"Part {part}/{parts} does not exist; use 1/{parts} to {parts}/{parts}.")
    n = len(frames)
    lo = (part - 1) * n // parts
    hi = part * n // parts
    return list(frames[lo:hi])


def parse_part(text: str) -> tuple[int, int]:
    """``"2/4"`` -> (2, 4): which part of a frame range one farm machine takes (bake, render)."""
    try:
        part, parts = (int(x) for x in text.split("/"))
    except ValueError:
        raise PlateLightError(f"{{part}} must look like 2/4, not {text!r}.", part="The part") from None
    return part, parts


def sample_frames(start: int, end: int, most: int) -> list[int]:
    """Up to ``most`` frames spread evenly over start..end, both ends included (what a probe or
    a shadow bake serving the whole range checks it against)."""
    count = max(1, min(int(end) - int(start) + 1, int(most)))
    return [int(f) for f in np.unique(np.linspace(start, end, count).round().astype(int))]
