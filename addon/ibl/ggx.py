"""GGX formulas the engine's brute-force tables share (bpy-free)."""
from __future__ import annotations

import numpy as np


def smith_lambda(alpha_squared: float, cos) -> np.ndarray:
    """Smith's Lambda of an isotropic GGX surface (alpha^2) for directions at cos = N.w from its
    normal: G1 = 1 / (1 + Lambda), height-correlated G2 = 1 / (1 + Lambda_v + Lambda_l)."""
    c = np.clip(cos, 1e-9, 1.0)
    return (np.sqrt(1.0 + alpha_squared * (1.0 - c * c) / (c * c)) - 1.0) / 2.0
