"""The one-run benchmark protocol's arithmetic, without Blender: scores, the truth's own ceiling,
repeats, the run's header, and the comparisons against the reference route.

bench_shot.py renders; this module decides what the renders show, so a test can check it on
images whose answer is known (tests/test_shot_protocol.py)."""
from __future__ import annotations

import datetime
import math
import os
import platform
import subprocess
import uuid

import numpy as np

# the truth is the mean of two halves of independent seeds: its own noise has a quarter of the
# halves' difference's variance
HALVES_TO_MEAN_DB = 10 * math.log10(4.0)
# a score this close to the truth's ceiling cannot tell a better route from a worse one
CEILING_MARGIN_DB = 1.0
# the reference route has converged where its last step in samples gains less than this
CONVERGED_STEP_DB = 0.3
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def pooled_psnr(images, truths, masks, peak: float) -> float:
    """PSNR (dB) of ``images`` against ``truths`` over ``masks``, pooled over the frames, with
    both clipped to [0, peak] (a firefly counts once, as the viewer sees it)."""
    err = np.concatenate([((np.clip(a, 0, peak) - np.clip(b, 0, peak))[m] ** 2).ravel()
                          for a, b, m in zip(images, truths, masks)])
    if err.size == 0:
        raise ValueError("the masks select no pixel")
    return float(10 * np.log10(peak ** 2 / max(float(err.mean()), 1e-20)))


def truth_ceiling(halves_a, halves_b, masks, peak: float) -> float:
    """The best PSNR any route can score against the mean of two independent truth halves: the
    mean's own noise, measured as the halves' difference (variance 4x the mean's)."""
    return pooled_psnr(halves_a, halves_b, masks, peak) + HALVES_TO_MEAN_DB


def peak_of(truths) -> float:
    """The PSNR peak: the truths' 99.5th percentile (a sun or a highlight does not set it)."""
    return float(np.percentile(np.concatenate([t.ravel() for t in truths]), 99.5))


def shadow_mask(truth, plate, object_near, darker_than=0.97):
    """Pixels the truth shows more than 3 % darker than the plate, away from the object."""
    return ((truth @ LUMINANCE) < darker_than * (plate @ LUMINANCE)) & ~object_near


def sensor_noise(image, strength: float, seed: int):
    """Footage's noise: signal-dependent shot noise plus read noise, slightly correlated
    (demosaicking), ``strength`` the standard deviation at mid-grey 0.18."""
    import cv2

    if strength <= 0:
        return np.zeros_like(image)
    rng = np.random.default_rng(seed)
    white = rng.standard_normal(image.shape).astype(np.float32)
    grain = cv2.GaussianBlur(white, (0, 0), 0.7)
    grain /= grain.std()
    sigma = strength * np.sqrt((0.8 * np.clip(image, 0, None) + 0.2 * 0.18) / 0.18)
    return (grain * sigma).astype(np.float32)


def median_and_spread(values) -> tuple[float, float]:
    """(median, (max - min) / median) of repeated timings."""
    values = [float(v) for v in values]
    median = float(np.median(values))
    return median, (max(values) - min(values)) / median if median > 0 else 0.0


def per_frame_seconds(bake_s, setup_s, first_s, warm_s, shot_frames) -> float:
    """A shot's seconds per frame: the once-per-shot work and the first frame, then warm frames."""
    return (bake_s + setup_s + first_s + (shot_frames - 1) * warm_s) / shot_frames


def run_header(repo, blender_version: str) -> dict:
    """What every row of one invocation carries: commit, run id, machine, date, Blender."""
    try:
        commit = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short=12", "HEAD"],
                                capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, check=True).stdout.strip()
        commit += "+changes" if dirty else ""
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return dict(commit=commit, run=uuid.uuid4().hex[:12], cpu=cpu, cores=os.cpu_count(),
                date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
                blender=blender_version, load_at_start=os.getloadavg()[0])


def reference_convergence(points) -> tuple[float, float, bool]:
    """(PSNR, seconds, converged) of the reference route's converged point: its best PSNR, at
    the fastest time that reaches within CONVERGED_STEP_DB of it; converged when its last step
    in samples gained less than CONVERGED_STEP_DB. ``points``: (seconds, PSNR) by samples."""
    points = list(points)
    best = max(p for _, p in points)
    seconds = min(t for t, p in points if p >= best - CONVERGED_STEP_DB)
    converged = len(points) > 1 and points[-1][1] - points[-2][1] < CONVERGED_STEP_DB
    return best, seconds, converged


def speedup_at_equal_psnr(ours: tuple[float, float], reference) -> tuple[float | None, str]:
    """How many times faster ``ours`` (seconds, PSNR) is than the reference route at the same
    PSNR: the reference's time to reach it, interpolated in log time along its best-so-far
    curve. (None, why) where no such time was measured: the reference never reached it, or
    reached it at its fastest point already (its time there only bounds the speed-up)."""
    t, p = ours
    ref = sorted(reference)
    times = np.log([s for s, _ in ref])
    best = np.maximum.accumulate([q for _, q in ref])
    if p > best[-1]:
        return None, "not reached by the reference"
    if p <= best[0]:
        return None, "the reference's fastest point is as good"
    # the first point where the best-so-far reaches p, and the one before it
    k = int(np.argmax(best >= p))
    f = (p - best[k - 1]) / (best[k] - best[k - 1])
    return float(math.exp(times[k - 1] + f * (times[k] - times[k - 1]))) / t, "measured"


def gain_at_equal_time(ours: tuple[float, float], reference) -> float | None:
    """dB ``ours`` scores above the reference at its own time, the reference interpolated in
    log time; None outside the reference's measured times (no extrapolation)."""
    t, p = ours
    ref = sorted(reference)
    times = np.log([s for s, _ in ref])
    if not times[0] <= math.log(t) <= times[-1]:
        return None
    return p - float(np.interp(math.log(t), times, [q for _, q in ref]))


def at_ceiling(psnr: float, ceiling: float) -> bool:
    """A score within CEILING_MARGIN_DB of the truth's ceiling makes no claim."""
    return psnr > ceiling - CEILING_MARGIN_DB


def interleaved(rows_per_route: dict, repeats: int):
    """The order one scene's rows run in: every row once, then every row again, ``repeats``
    times, so a change in the machine's load falls on all routes alike. Yields (repeat, key)."""
    for repeat in range(repeats):
        for key in rows_per_route:
            yield repeat, key
