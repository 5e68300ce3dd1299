"""The Debevec response recovered from three real JPEG brackets (shared/data/real/
brackets_frobisher, EXIF times) against colour-hdri's curve from the same photos."""
from __future__ import annotations

import numpy as np
import pytest

import real_photos as rp
from platelight.addon.capture import hdr_merge

pytestmark = pytest.mark.skipif(not rp.FROBISHER.is_dir(), reason="shared/data/real is not here")


def response_error(response_rgb: np.ndarray) -> np.ndarray:
    """|ratio - 1| on codes 32..223 after each channel's scale (a response is known up to one)."""
    reference = np.load(rp.FROBISHER / "test_camera_response_function_Debevec1997_crfs.npy")
    z = np.arange(32, 224)
    ratio = response_rgb[z] / reference[z]
    return np.abs(ratio / np.median(ratio, axis=0) - 1)


def test_response_matches_colour_hdri():
    images, times = hdr_merge.read_brackets(sorted(rp.FROBISHER.glob("IMG_*.jpg")))
    assert times.tolist() == pytest.approx([1 / 8, 1, 8])          # from EXIF
    err = response_error(hdr_merge.recover_response(images, times)[:, ::-1])
    assert np.median(err) <= 0.04 and np.percentile(err, 90) <= 0.08
