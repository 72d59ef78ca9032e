"""Position and velocity fixes of an antenna (:class:`PositionFix`,
:class:`VelocityFix`) and their forms with the lever arm estimated
(:class:`LeverPositionFix`, :class:`LeverVelocityFix`)."""
from __future__ import annotations

import math

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.fusion.measurements.base import Epoch, NavRow
from sinslab.fusion.measurements.jacobians import add_rate_H
from sinslab.fusion.measurements.schedule import Timed, robust_weighting

__all__ = ["PositionFix", "VelocityFix", "LeverPositionFix", "LeverVelocityFix"]


class PositionFix(Timed):
    """Position fixes of an antenna (2-D or 3-D) against one stream.

    ``z = [(L − L_fix)(R_M+h), (λ − λ_fix)(R_N+h)cosL, h − h_fix] − v_ant·Δt``
    (north, east, up [m]; the fix extrapolated from its validity time to the epoch with
    the antenna velocity, Δt = t_epoch − t_valid), with the lever arm ``l`` (IMU ->
    antenna, body axes) added as ``+ C_b^n l`` and in H as ``(C_b^n l)×`` on φ (rows
    reordered north, east, up). The antenna velocity is ``v + C_b^n (ω_ib^b × l)``; the
    extrapolation puts ``−Δt ∂v_ant/∂x`` in H (δv, and with a lever arm φ and every block
    feeding the gyro). With a ``fix_error`` block in the layout
    (:func:`sinslab.nav.errstate.fix_position_error`: the fixes' time-correlated error e,
    east, north, up) ``z = δp − e`` and H carries −1 on it.

    Parameters
    ----------
    t_valid : array_like, shape (J,)
        Validity times [s].
    pos : array_like, shape (J, 3) or (J, 2)
        ``[lat, lon, h]`` [rad, rad, m]; ``(J, 2)`` only for a 2-state position block.
    sigma : array_like, shape (J, m) or (m,)
        Standard deviations north, east[, up] [m].
    t_arrive : array_like, shape (J,), optional
        Arrival times [s] (default: the validity times).
    lever_arm : array_like (3,), optional
        IMU -> antenna in body axes [m].
    outages, windows
        See :func:`arrival_epochs`.
    stream : int
        Index of the stream the fix is compared with.
    robust : RobustWeighting, float or str, optional
        Inflate R where the innovation is inconsistent
        (:class:`sinslab.fusion.measurements.schedule.RobustWeighting`: Chang's whole-fix
        rule for a probability, Huber or IGG-III row weights; None: never). The times and
        largest factors are kept in ``downweighted``.
    """

    def __init__(self, t_valid, pos, sigma, *, t_arrive=None, lever_arm=None, outages=(),
                 windows=None, stream=0, robust=None):
        self._init_times(t_valid, t_arrive, outages, windows)
        self.robust = robust_weighting(robust)
        self.downweighted = []
        self.pos = np.asarray(pos, dtype=float)
        J = self.t_valid.size
        if self.pos.ndim != 2 or self.pos.shape[0] != J or self.pos.shape[1] not in (2, 3):
            raise ValueError(f"fix positions must have shape ({J}, 3) or ({J}, 2), got {self.pos.shape}")
        sigma = np.asarray(sigma, dtype=float)
        self.sigma = np.broadcast_to(sigma, (J, sigma.shape[-1]))
        lever = None if lever_arm is None else np.asarray(lever_arm, dtype=float).reshape(3)
        self.lever = None if (lever is None or not np.any(lever)) else lever
        self.stream = int(stream)

    def size(self, layout):
        return 3 if layout.slice("dp").stop - layout.slice("dp").start == 3 else 2

    def antenna(self, nr: NavRow):
        """``(C_b^n, C_b^n l, v_ant, C_b^n (ω×l))`` of a row (lever terms None without a lever arm)."""
        if self.lever is None:
            return None, None, nr.vel, None
        C = nr.C_bn
        Cl = C @ self.lever
        vlev = C @ np.cross(nr.omega_b, self.lever)
        return C, Cl, nr.vel + vlev, vlev

    def matrices(self, ep: Epoch):
        return self._robust(ep, *self._zHR(ep))

    def _places(self, lay):
        """``(δp slice, rows, φ slice, fix-error slice, δv slice)`` of a layout (None where it
        has no such block), looked up once for the layout of the run."""
        kept = self.__dict__.get("_layout_places")
        if kept is not None and kept[0] is lay:
            return kept[1]
        s_pos = lay.slice("dp")
        names = lay.names
        places = (s_pos, self.size(lay), lay.slice("phi") if "phi" in names else None, lay.find("fix_error"),
                  lay.slice("dv") if "dv" in names else None)
        self._layout_places = (lay, places)
        return places

    def _zHR(self, ep: Epoch):
        j = ep.item
        lay = ep.layout
        nr = ep.streams[self.stream]
        s_pos, n_z, s_phi, fe, s_vel = self._places(lay)
        lat, lon, h = nr.lat, nr.lon, nr.h
        rm, rn = E.radii(lat, h)
        rm, rnc = float(rm), float(rn) * math.cos(lat)
        C, Cl, v_ant, _ = self.antenna(nr)
        z = np.empty(n_z)
        H = np.zeros((n_z, ep.n))
        if Cl is not None:
            H[0:3, s_phi] = A.skew(Cl)[[1, 0, 2]][:n_z]
        dtf = ep.t - self.t_valid[j]                 # fix extrapolated to the epoch
        dlon = A.wrap_pi_float(lon - self.pos[j, 1])
        z[0] = (lat - self.pos[j, 0]) * rm - v_ant[1] * dtf
        z[1] = dlon * rnc - v_ant[0] * dtf
        H[0, s_pos.start] = rm
        H[1, s_pos.start + 1] = rnc
        if n_z == 3:
            z[2] = (h - self.pos[j, 2]) - v_ant[2] * dtf
            H[2, s_pos.start + 2] = 1.0
        if Cl is not None:
            z[0:n_z] += Cl[[1, 0, 2]][:n_z]
        if fe is not None:
            # z = INS − fix = δp − e (e: the fix's own correlated error, east, north, up)
            H[0, fe.start + 1] = H[1, fe.start] = -1.0
            if n_z == 3:
                H[2, fe.start + 2] = -1.0
        if dtf != 0.0:
            # −Δt ∂v_ant/∂x: the INS antenna velocity that moved the fix to the epoch
            if s_vel is None:
                s_vel = lay.slice("dv")                 # raises: the layout has no δv block
            nv = s_vel.stop - s_vel.start
            Hv = np.zeros((3, ep.n))
            Hv[:nv, s_vel] = np.eye(nv)
            if Cl is not None:
                Hv[:, s_phi] = A.skew(C @ np.cross(nr.omega_b, self.lever))
                add_rate_H(Hv, lay, -C @ A.skew(self.lever), nr.omega_b)
            H -= dtf * Hv[[1, 0, 2]][:n_z]
        return z, H, self.sigma[j, :n_z] ** 2

    def _robust(self, ep, z, H, R):
        """``(z, H, R)`` with R inflated where the innovation is inconsistent (``robust``,
        :class:`RobustWeighting`); the times of the inflated fixes are kept in ``downweighted``."""
        if self.robust is None:
            return z, H, R
        R, f = self.robust.weigh(ep, z, H, R)
        if f > 1.0:
            self.downweighted.append((float(ep.t), f))
        return z, H, R


class VelocityFix(Timed):
    """Velocity fixes of an antenna (ENU, 3 components) against one stream.

    ``z = v + C_b^n (ω_ib^b × l) − v_fix`` [m/s]; ``H`` has ``I`` on δv and, with a lever
    arm, ``(C_b^n (ω×l))×`` on φ and ``−C_b^n (l×) ∂δω/∂x`` on every block feeding the
    gyro compensation (bias, Gauss–Markov, scale factors: :func:`add_rate_H`).

    Parameters
    ----------
    t_valid : array_like, shape (J,)
    vel : array_like, shape (J, 3)
        ENU [m/s].
    sigma : array_like, shape (J, 3) or (3,)
        [m/s].
    t_arrive, lever_arm, outages, windows, stream
        As in :class:`PositionFix`.
    """

    def __init__(self, t_valid, vel, sigma, *, t_arrive=None, lever_arm=None, outages=(),
                 windows=None, stream=0, robust=None):
        self._init_times(t_valid, t_arrive, outages, windows)
        self.robust = robust_weighting(robust)
        self.downweighted = []
        J = self.t_valid.size
        self.vel = np.asarray(vel, dtype=float).reshape(J, 3)
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (J, 3))
        lever = None if lever_arm is None else np.asarray(lever_arm, dtype=float).reshape(3)
        self.lever = None if (lever is None or not np.any(lever)) else lever
        self.stream = int(stream)

    def matrices(self, ep: Epoch):
        return PositionFix._robust(self, ep, *self._zHR(ep))

    def _zHR(self, ep: Epoch):
        j = ep.item
        lay = ep.layout
        nr = ep.streams[self.stream]
        v_ant = nr.vel
        H = np.zeros((3, ep.n))
        H[:, lay.slice("dv")] = np.eye(3)
        if self.lever is not None:
            C = nr.C_bn
            vlev = C @ np.cross(nr.omega_b, self.lever)
            v_ant = v_ant + vlev
            H[:, lay.slice("phi")] = A.skew(vlev)
            add_rate_H(H, lay, -C @ A.skew(self.lever), nr.omega_b)
        return v_ant - self.vel[j], H, self.sigma[j] ** 2


class LeverPositionFix(PositionFix):
    """:class:`PositionFix` with the antenna lever arm estimated: the block ``lever_block``
    (:func:`sinslab.nav.errstate.lever_arm`; None: the layout's one lever-arm block)
    holds ``δl = l_used − l_true`` and
    ``∂z/∂δl = C_b^n`` (rows north, east, up) ``− C_b^n (ω×) Δt`` (extrapolation).
    ``lever_arm`` is the lever used (default zero, an unknown antenna offset)."""

    def __init__(self, t_valid, pos, sigma, *, lever_block=None, lever_arm=None, **kw):
        super().__init__(t_valid, pos, sigma, lever_arm=lever_arm, **kw)
        self.lever_block = lever_block

    def _zHR(self, ep: Epoch):
        z, H, R = super()._zHR(ep)
        nr = ep.streams[self.stream]
        C = nr.C_bn
        dtf = ep.t - self.t_valid[ep.item]
        n_z = z.size
        H[:, _lever_columns(ep.layout, self.lever_block)] = (C - dtf * C @ A.skew(nr.omega_b))[[1, 0, 2]][:n_z]
        return z, H, R


def _lever_columns(layout, name):
    """The columns of the lever-arm block ``name`` (None: the layout's one lever-arm block)."""
    sl = layout.find("lever_arm", name)
    if sl is None:
        raise ValueError(f"the lever-arm fixes need a lever-arm block (the layout has {list(layout.names)})")
    return sl


class LeverVelocityFix(VelocityFix):
    """:class:`VelocityFix` with the antenna lever arm estimated (``∂z/∂δl = C_b^n (ω×)``)."""

    def __init__(self, t_valid, vel, sigma, *, lever_block=None, lever_arm=None, **kw):
        super().__init__(t_valid, vel, sigma, lever_arm=lever_arm, **kw)
        self.lever_block = lever_block

    def _zHR(self, ep: Epoch):
        z, H, R = super()._zHR(ep)
        nr = ep.streams[self.stream]
        H[:, _lever_columns(ep.layout, self.lever_block)] = nr.C_bn @ A.skew(nr.omega_b)
        return z, H, R
