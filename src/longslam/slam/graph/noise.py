"""Noise models of the factors: diagonal sigmas, a full information matrix, robust kernels."""

from __future__ import annotations

import gtsam
import numpy as np

from longslam.core.errors import InputError

ROBUST_KERNELS = ("cauchy", "huber", "none")


def diagonal(sigmas: np.ndarray) -> gtsam.noiseModel.Base:
    return gtsam.noiseModel.Diagonal.Sigmas(np.asarray(sigmas, dtype=np.float64))


def gaussian(information: np.ndarray, ridge: float = 0.0) -> gtsam.noiseModel.Base:
    """A Gaussian of a symmetric positive-definite information matrix, or, with `ridge`, of one
    that may be singular (a registration's Hessian along a corridor): symmetrised, `ridge` * I
    added."""
    if ridge:
        information = 0.5 * (information + information.T) + ridge * np.eye(len(information))
    return gtsam.noiseModel.Gaussian.Information(information)


def robust(base: gtsam.noiseModel.Base, kernel: str, k: float) -> gtsam.noiseModel.Base:
    """`base` under an M-estimator: "cauchy" (its influence falls off for large residuals, so a
    grossly wrong closure hardly bends the graph), "huber" (a constant pull) or "none"."""
    if kernel == "none":
        return base
    if kernel == "cauchy":
        estimator = gtsam.noiseModel.mEstimator.Cauchy.Create(k)
    elif kernel == "huber":
        estimator = gtsam.noiseModel.mEstimator.Huber.Create(k)
    else:
        raise InputError(f"robust_kernel must be one of {', '.join(ROBUST_KERNELS)}, got {kernel!r}")
    return gtsam.noiseModel.Robust.Create(estimator, base)
