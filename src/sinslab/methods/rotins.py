"""Joint error model of two rotation-modulated INS on one carrier, its online evaluation
index and its observability along a rotate-stop schedule.

Wang, Wu et al. (2018), online evaluation of a dual-axis rotation-modulated INS against a
single-axis one on the same ship: both INS navigate on their own; a joint Kalman filter of
the pair (INS 1, INS k) uses the difference of their horizontal positions and velocities
as measurement and estimates, among others, INS 1's azimuth gyro drift ε_z1. The
scatter of that estimate over a sliding window is the evaluation index of INS k's random
error.

Frames and units as in :mod:`sinslab.nav.errstate` (ENU navigation frame, RFU body
frames, errors computed minus true, SI inside).
"""
from __future__ import annotations

from sinslab.nav.errstate import DifferenceModel, accel_bias, gyro_bias

__all__ = ["joint_rotation_model"]


def joint_rotation_model(gyro_noise1=0.0, gyro_noisek=0.0, accel_noise1=0.0, accel_noisek=0.0,
                         radius_derivatives=False) -> DifferenceModel:
    """The 17-state joint error model of INS 1 (single-axis) and INS k (dual-axis)
    (Wang, Wu et al. 2018, eqs 1–8).

    State order (paper eq 1)::

        x1 = [δL δλ δvE δvN]_1k                      (differences, 1 − k)
        x2 = [φE φN φU]_1k, ε_1 (x y z, body 1), ε_k (x y z, body k),
             ∇_1 (x y, body 1), ∇_k (x y, body k)

    Horizontal core (vertical channel damped by a depth gauge), random-constant drifts
    and biases; the noise vector is ``[w_g1 (3), w_a1 (x,y), w_gk (3), w_ak (x,y)]``
    (paper eq 7 orders gyros first; only the column order differs). With
    ``radius_derivatives=False`` F equals the paper's eqs 3–6 (tested).

    Parameters
    ----------
    gyro_noise1, gyro_noisek : float or (3,)
        Gyro white noise (ARW) of INS 1 / INS k [rad/√s].
    accel_noise1, accel_noisek : float or (2,)
        Horizontal accelerometer white noise (VRW) of INS 1 / INS k [m/s/√s].
    radius_derivatives : bool
        Keep the dR/dL and ∂g/∂L terms (exact Jacobian) instead of the paper's F.

    Returns
    -------
    DifferenceModel
        ``F(nav1, navk)`` of shape ``S + (17, 17)``; block names ``dp dv phi eps_1 eps_k
        nabla_1 nabla_k``.
    """
    return DifferenceModel(
        "horizontal", [gyro_bias(name="eps"), accel_bias("xy", name="nabla")],
        [gyro_bias(name="eps"), accel_bias("xy", name="nabla")],
        gyro_noise1, gyro_noisek, accel_noise1, accel_noisek, accel_noise_axes="xy",
        order=["dp", "dv", "phi", "eps_1", "eps_k", "nabla_1", "nabla_k"],
        radius_derivatives=radius_derivatives)
