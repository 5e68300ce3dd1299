"""Content hashes of a probe's inputs: equal hash means an identical probe, so the bake is skipped.

The Blender glue describes what a probe sees as plain data (numbers, strings, lists, dicts and
numpy arrays); this module turns it into a stable digest. Floats are rounded to 6 significant
digits so that re-evaluating the same transform (float noise of ~1e-7) is still a cache hit."""
from __future__ import annotations

import hashlib
import json
import math

import numpy as np

HASH_VERSION = 2          # bump when what goes into a hash or a probe render changes, so old caches go stale


def _canonical(value):
    if isinstance(value, float):
        if not math.isfinite(value):
            return repr(value)
        return float(f"{value:.6g}")
    if isinstance(value, (bool, int, str)) or value is None:
        return value
    if isinstance(value, np.ndarray):
        arr = np.asarray(value, dtype=np.float64)
        # 6 significant digits relative to the array's magnitude (tiny jitter is not a change).
        scale = float(np.max(np.abs(arr))) if arr.size else 0.0
        quantum = 10 ** (math.floor(math.log10(scale)) - 5) if scale > 0 and math.isfinite(scale) else 1.0
        q = np.round(arr / quantum).astype(np.int64)
        return {"shape": list(arr.shape), "q": quantum,
                "sha1": hashlib.sha1(q.tobytes()).hexdigest()}
    if isinstance(value, np.generic):
        return _canonical(value.item())
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    return repr(value)


def content_hash(description) -> str:
    """SHA-1 hex digest of a plain-data description of everything a probe depends on."""
    text = json.dumps({"v": HASH_VERSION, "d": _canonical(description)}, sort_keys=True,
                      separators=(",", ":"))
    return hashlib.sha1(text.encode()).hexdigest()
