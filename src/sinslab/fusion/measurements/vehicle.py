"""Measurements of a wheeled vehicle's velocity in its own axes: the non-holonomic
constraint (:class:`NonHolonomic`), a body-frame velocity (:class:`BodyVelocity`) and the
odometer (:class:`Odometer`)."""
from __future__ import annotations

import math

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.fusion.measurements.base import Epoch
from sinslab.fusion.measurements.jacobians import add_rate_H, vehicle_from_body
from sinslab.fusion.measurements.schedule import Timed, _OnEpochs, _sigma

__all__ = ["NonHolonomic", "BodyVelocity", "Odometer"]


def _vehicle_velocity(nr, lay, n, Cvb, lever, lever_block=None, mount_block=None):
    """Velocity of a vehicle point in vehicle axes and its Jacobian.

    ``v^v = C_b^v (C̃_n^b ṽ^n + ω̃_ib^b × l)`` [m/s] (l: IMU -> point, body axes [m]);
    ``∂/∂φ = −C_b^v C_n^b (v^n×)``, ``∂/∂δv = C_b^v C_n^b``, ``∂/∂δω = −C_b^v (l×)``,
    ``∂/∂δl = C_b^v (ω×)`` (lever error state, computed − true, when ``lever_block``),
    ``∂/∂ψ = (v^v×)`` (``mount_block``: small angles ψ [rad] of the mount in use, vehicle
    axes, ``C̃_b^v = (I − ψ×) C_b^v``; the true mount is ``(I + ψ×) C̃_b^v``).
    """
    Cnb = nr.C_bn.T
    w = nr.omega_b
    vb = Cnb @ nr.vel + np.cross(w, lever)
    H = np.zeros((3, n))
    sv = lay.slice("dv")
    k = sv.stop - sv.start
    H[:, sv] = (Cvb @ Cnb)[:, :k]
    H[:, lay.slice("phi")] = -Cvb @ Cnb @ A.skew(nr.vel)
    add_rate_H(H, lay, -Cvb @ A.skew(lever), w)
    if lever_block is not None:
        H[:, lay.find("lever_arm", lever_block)] = Cvb @ A.skew(w)
    vv = Cvb @ vb
    if mount_block is not None:
        sl = lay.find("installation", mount_block)
        H[:, sl] = A.skew(vv)[:, ["xyz".index(a) for a in lay.blocks[lay.names.index(mount_block)].axes]]
    return vv, H


def _lever(lever_arm):
    return np.zeros(3) if lever_arm is None else np.asarray(lever_arm, dtype=float).reshape(3)


class NonHolonomic(_OnEpochs):
    """Non-holonomic constraint of a wheeled vehicle: no lateral and no vertical velocity
    of the wheel contact point in vehicle axes (RFU: x right, z up).

    ``z = [v^v_x, v^v_z]`` of :func:`_vehicle_velocity` [m/s].

    Parameters
    ----------
    sigma : float or array_like (2,)
        Lateral, vertical [m/s] (the constraint is violated by skid and suspension).
    mount : see :func:`vehicle_from_body`
        IMU body -> vehicle axes.
    lever_arm : array_like (3,), optional
        IMU -> constraint point (e.g. rear-axle centre), body axes [m].
    intervals : sequence of (start, end) [s], optional
        Where the constraint holds (default: every epoch).
    lever_block : str, optional
        Name of a :func:`sinslab.nav.errstate.lever_arm` block estimating the lever error.
    mount_block : str, optional
        Name of a :func:`sinslab.nav.errstate.installation` block (axes ``"xz"``: pitch and
        yaw; roll is unobservable) estimating the mount's small-angle error.
    every, stream, gate
        As in :class:`ZeroVelocity`.
    pitch_gradient : float, optional
        Pitch of the body on its suspension per longitudinal acceleration [rad per m/s²]
        (a car dips its nose when braking). The vertical velocity it gives the constraint
        point, ``e = v_y k a_y`` (vehicle axes, ``a = C_b^n f^b + g^n``), is not modelled
        but systematic over a manoeuvre: its variance is added to the vertical row's,
        multiplied by the number of updates in ``correlation_time`` (it does not average
        out like white noise over them). 0: the fixed σ alone.
    correlation_time : float, optional
        [s] over which that error stays the same (a braking or accelerating manoeuvre).
    dt : float, optional
        Filter epoch [s]; the updates come every ``every * dt``.
    """

    rows = (0, 2)

    def __init__(self, sigma=0.1, *, mount=None, lever_arm=None, intervals=None, lever_block=None,
                 every=1, stream=0, gate=None, mount_block=None, pitch_gradient=0.0,
                 correlation_time=1.0, dt=None):
        self._init_sched(intervals, every, stream, gate)
        self.sigma = _sigma(sigma, 2, "NHC")
        self.Cvb = vehicle_from_body(mount)
        self.lever = _lever(lever_arm)
        self.lever_block = lever_block
        self.mount_block = mount_block
        self.pitch_gradient = float(pitch_gradient)
        if not (math.isfinite(self.pitch_gradient) and self.pitch_gradient >= 0):
            raise ValueError(f"NHC pitch gradient must be finite and >= 0, got {pitch_gradient}")
        if self.pitch_gradient > 0 and not (dt is not None and dt > 0 and correlation_time > 0):
            raise ValueError("an NHC pitch gradient needs the filter epoch dt > 0 and a correlation time > 0")
        self.n_corr = max(1.0, correlation_time / (self.every * dt)) if self.pitch_gradient > 0 else 1.0

    def matrices(self, ep: Epoch):
        nr = ep.streams[self.stream]
        vv, H = _vehicle_velocity(nr, ep.layout, ep.n, self.Cvb, self.lever,
                                  self.lever_block, self.mount_block)
        r = list(self.rows)
        R = self.sigma ** 2
        if self.pitch_gradient > 0:
            Cbn = nr.C_bn
            acc = Cbn @ nr.f_b + E.gravity_vector(nr.lat, nr.h)
            av = self.Cvb @ (Cbn.T @ acc)                   # vehicle axes: y forward
            e = self.pitch_gradient * (vv[1] * av[1])
            R = R + np.array([0.0, self.n_corr * e * e])
        return vv[r], H[r], R


class BodyVelocity(Timed):
    """A measured 3-D velocity of a vehicle point in vehicle axes (e.g. a Doppler
    velocity log, or wheel speed with the non-holonomic zeros).

    ``z = v^v(computed) − v_meas`` [m/s], linearised by :func:`_vehicle_velocity`.

    Parameters
    ----------
    t : array_like (J,)
        Validity times [s].
    vel : array_like (J, 3)
        Vehicle-axis velocity [m/s].
    sigma : array_like (3,) or (J, 3)
        [m/s].
    mount, lever_arm, lever_block, stream
        As in :class:`NonHolonomic`.
    t_arrive, outages, windows
        As in :class:`PositionFix`.
    """

    def __init__(self, t, vel, sigma, *, mount=None, lever_arm=None, lever_block=None,
                 t_arrive=None, outages=(), windows=None, stream=0):
        self._init_times(t, t_arrive, outages, windows)
        J = self.t_valid.size
        self.vel = np.asarray(vel, dtype=float).reshape(J, 3)
        if not np.all(np.isfinite(self.vel)):
            raise ValueError("body velocities contain NaN/inf")
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (J, 3))
        if not np.all(self.sigma > 0):
            raise ValueError("body velocity sigma must be > 0")
        self.Cvb = vehicle_from_body(mount)
        self.lever = _lever(lever_arm)
        self.lever_block = lever_block
        self.stream = int(stream)

    def matrices(self, ep: Epoch):
        vv, H = _vehicle_velocity(ep.streams[self.stream], ep.layout, ep.n, self.Cvb, self.lever,
                                  self.lever_block)
        return vv - self.vel[ep.item], H, self.sigma[ep.item] ** 2


class Odometer(_OnEpochs):
    """Wheel speed: the forward velocity ``v^v_y`` of the wheel point, from a time series
    with its own time stamps, linearly interpolated to the filter epochs it spans.

    The scale-factor state ``k`` (an :func:`sinslab.nav.errstate.odometer_scale` block,
    when ``scale_block`` names one) is defined by ``v^v_y = (1 − k) s̃`` for the reading
    ``s̃``: then ``z = v^v_y(computed) − s̃ = δv^v_y − k s̃`` holds exactly, ``∂z/∂k = −s̃``.
    A reading ``s̃ = (1 + k_s) v^v_y`` corresponds to ``k = k_s / (1 + k_s)`` (equal to
    first order; compare estimates with that, not with ``k_s``). With
    ``nhc_sigma`` the non-holonomic zeros ``v^v_x, v^v_z`` are stacked as rows 2, 3.

    Parameters
    ----------
    t : array_like (J,)
        Odometer time stamps [s], strictly increasing.
    speed : array_like (J,)
        Forward speed [m/s], finite and >= 0.
    sigma : float
        Speed noise [m/s] at one filter epoch (include quantisation: step/√12).
    mount, lever_arm, lever_block, intervals, every, stream, gate
        As in :class:`NonHolonomic` (``lever_arm``: IMU -> wheel point).
    scale_block : str or None
        Name of the odometer scale-factor block (None: the layout's one
        :func:`~sinslab.nav.errstate.odometer_scale` block, if it has one).
    nhc_sigma : float or array_like (2,), optional
        Also constrain lateral and vertical velocity [m/s].
    """

    def __init__(self, t, speed, sigma, *, mount=None, lever_arm=None, lever_block=None,
                 scale_block=None, nhc_sigma=None, intervals=None, every=1, stream=0, gate=None):
        self._init_sched(intervals, every, stream, gate)
        self.t_odo = np.asarray(t, dtype=float).ravel()
        self.speed = np.asarray(speed, dtype=float).ravel()
        if self.t_odo.size < 2 or self.speed.shape != self.t_odo.shape:
            raise ValueError(f"odometer: {self.t_odo.size} times and {self.speed.size} speeds "
                             "(need >= 2 of each, equal numbers)")
        if not (np.all(np.isfinite(self.t_odo)) and np.all(np.diff(self.t_odo) > 0)):
            raise ValueError("odometer times must be finite and strictly increasing")
        if not np.all(np.isfinite(self.speed)) or np.any(self.speed < 0):
            raise ValueError("odometer speeds must be finite and >= 0")
        self.sigma = _sigma(sigma, 1, "odometer")
        self.nhc_sigma = None if nhc_sigma is None else _sigma(nhc_sigma, 2, "NHC")
        self.Cvb = vehicle_from_body(mount)
        self.lever = _lever(lever_arm)
        self.lever_block = lever_block
        self.scale_block = scale_block

    def _keep(self, t):
        keep = super()._keep(t)
        keep &= (t >= self.t_odo[0] - 1e-9) & (t <= self.t_odo[-1] + 1e-9)
        return keep

    def epochs(self, grid):
        t = grid.t
        if self.t_odo[-1] < t[0] or self.t_odo[0] > t[-1]:
            raise ValueError(f"odometer times {self.t_odo[0]:.3f}..{self.t_odo[-1]:.3f} s do not "
                             f"overlap the filter epochs {t[0]:.3f}..{t[-1]:.3f} s")
        return super().epochs(grid)

    def reading(self, t):
        """Wheel speed [m/s] interpolated at ``t`` [s]."""
        return float(np.interp(t, self.t_odo, self.speed))

    def matrices(self, ep: Epoch):
        vv, H = _vehicle_velocity(ep.streams[self.stream], ep.layout, ep.n, self.Cvb, self.lever,
                                  self.lever_block)
        s = self.reading(ep.t)
        rows = [1] if self.nhc_sigma is None else [1, 0, 2]
        z = vv[rows]
        z[0] -= s
        H = H[rows]
        sk = ep.layout.find("odometer_scale", self.scale_block)
        if sk is not None:
            H[0, sk] = -s
        R = self.sigma ** 2 if self.nhc_sigma is None else np.r_[self.sigma, self.nhc_sigma] ** 2
        return z, H, R
