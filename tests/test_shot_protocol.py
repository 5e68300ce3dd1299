"""The shot benchmark's arithmetic on images and timings whose answers are known."""
import math

import numpy as np
import pytest

import shot_protocol as sp


def test_psnr_of_a_known_pair_over_its_mask():
    truth = np.full((40, 60, 3), 0.5, np.float32)
    image = truth.copy()
    mask = np.zeros((40, 60), bool)
    mask[10:20, 10:30] = True
    image[mask] += 0.01                         # MSE 1e-4 inside the mask, 0 outside
    image[~mask] += 0.3                         # what the mask leaves out does not count
    assert sp.pooled_psnr([image], [truth], [mask], 1.0) == pytest.approx(40.0, abs=1e-3)
    # pooled over frames: a second frame with MSE 3e-4 makes the mean 2e-4
    image2 = truth.copy()
    image2[mask] += math.sqrt(3e-4)
    assert sp.pooled_psnr([image, image2], [truth, truth], [mask, mask], 1.0) == pytest.approx(
        10 * math.log10(1 / 2e-4), abs=1e-3)
    with pytest.raises(ValueError):
        sp.pooled_psnr([image], [truth], [np.zeros_like(mask)], 1.0)


def test_truth_ceiling_is_the_mean_of_the_halves_own_noise():
    """A perfect route scored against the mean of two noisy halves scores the ceiling."""
    rng = np.random.default_rng(3)
    clean = rng.uniform(0.2, 0.8, (200, 300, 3)).astype(np.float32)
    sigma = 0.02
    a = clean + rng.normal(0, sigma, clean.shape).astype(np.float32)
    b = clean + rng.normal(0, sigma, clean.shape).astype(np.float32)
    mask = np.ones(clean.shape[:2], bool)
    ceiling = sp.truth_ceiling([a], [b], [mask], 1.0)
    assert ceiling == pytest.approx(10 * math.log10(1 / (sigma ** 2 / 2)), abs=0.05)
    perfect = sp.pooled_psnr([clean], [(a + b) / 2], [mask], 1.0)
    assert perfect == pytest.approx(ceiling, abs=0.05)
    assert sp.at_ceiling(perfect - 0.5, ceiling) and not sp.at_ceiling(ceiling - 1.5, ceiling)


def test_shadow_mask_takes_what_is_darker_away_from_the_object():
    plate = np.full((10, 10, 3), 0.5, np.float32)
    truth = plate.copy()
    truth[2:5, 2:5] *= 0.9                      # a shadow
    truth[7, 7] *= 0.99                         # within the 3 % noise margin
    near = np.zeros((10, 10), bool)
    near[2, 2] = True                           # the object's edge
    mask = sp.shadow_mask(truth, plate, near)
    assert mask.sum() == 8 and not mask[2, 2] and not mask[7, 7]


def test_speed_up_interpolates_the_reference_in_log_time_and_says_when_unmeasured():
    reference = [(1.0, 30.0), (2.0, 33.0), (4.0, 36.0)]
    value, why = sp.speedup_at_equal_psnr((0.5, 34.5), reference)
    assert why == "measured" and value == pytest.approx(2 * math.sqrt(2) / 0.5)
    assert sp.speedup_at_equal_psnr((0.5, 37.0), reference) == (None, "not reached by the reference")
    assert sp.speedup_at_equal_psnr((0.5, 29.0), reference)[0] is None
    # a reference that gets worse with samples is read along its best so far
    value, _ = sp.speedup_at_equal_psnr((1.0, 32.0), [(1.0, 30.0), (2.0, 34.0), (4.0, 31.0)])
    assert value == pytest.approx(2 ** 0.5)


def test_gain_at_equal_time_is_not_extrapolated():
    reference = [(1.0, 30.0), (4.0, 36.0)]
    assert sp.gain_at_equal_time((2.0, 35.0), reference) == pytest.approx(2.0)
    assert sp.gain_at_equal_time((0.5, 35.0), reference) is None
    assert sp.gain_at_equal_time((8.0, 35.0), reference) is None


def test_reference_convergence_and_its_flag():
    best, seconds, converged = sp.reference_convergence([(1, 30.0), (4, 38.0), (16, 40.1), (64, 40.2)])
    assert (best, seconds, converged) == (40.2, 16, True)
    assert not sp.reference_convergence([(1, 30.0), (4, 38.0), (16, 40.1)])[2]


def test_rows_run_interleaved_and_timings_report_median_and_spread():
    plan = {("a", 1): [], ("b", 4): []}
    assert list(sp.interleaved(plan, 3)) == [(0, ("a", 1)), (0, ("b", 4)), (1, ("a", 1)), (1, ("b", 4)),
                                             (2, ("a", 1)), (2, ("b", 4))]
    assert sp.median_and_spread([2.0, 1.0, 3.0]) == (2.0, 1.0)
    assert sp.per_frame_seconds(24.0, 0.0, 1.0, 1.0, 24) == pytest.approx(2.0)


def test_sensor_noise_has_the_asked_strength_at_mid_grey():
    grey = np.full((200, 200, 3), 0.18, np.float32)
    grain = sp.sensor_noise(grey, 0.01, seed=1)
    assert grain.std() == pytest.approx(0.01, rel=0.05) and abs(grain.mean()) < 1e-3
    assert not sp.sensor_noise(grey, 0.0, seed=1).any()
    assert np.array_equal(grain, sp.sensor_noise(grey, 0.01, seed=1))
