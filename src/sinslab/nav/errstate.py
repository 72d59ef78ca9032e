"""Error-state models of strapdown INS (φ-angle family, ENU).

Conventions (binding for every model in this module)
-----------------------------------------------------
- Navigation frame n = ENU, body frame b = RFU (IMU axes x right, y forward, z up).
- Every error is **computed minus true**:

  * attitude: the misalignment φ (rad, n frame) of the computed frame n',
    ``C_b^{n'} = (I − φ×) C_b^n`` (the convention of :mod:`sinslab.core.attitude`), i.e. ``φ = attitude.misalignment(C_true, C_comp)``;
  * velocity: ``δv^n = ṽ^n − v^n`` [m/s];
  * position: ``δp = [δL, δλ, δh] = p̃ − p`` [rad, rad, m];
  * sensors: ``ω̃_ib^b = ω_ib^b + δω_ib^b``, ``f̃^b = f^b + δf^b`` (measured minus true), so a
    positive gyro bias ε makes the gyro read high.

- The continuous model is ``ẋ = F(t) x + G(t) w`` with ``E[w(t) w(s)ᵀ] = diag(q) δ(t − s)``;
  ``q`` holds spectral densities in SI (gyro white noise [rad²/s] = ARW², accelerometer white
  noise [(m/s²)²/Hz = m²/s³] = VRW², Gauss–Markov driving noise ``2σ²/τ``).

Core equations (Savage; PSINS ``etm``) with ω_in = ω_ie + ω_en::

    φ̇  = −ω_in×φ + δω_in − C_b^n δω_ib^b                          (Maa, Mav, Map)
    δv̇ = f^n×φ + C_b^n δf^b − (2ω_ie+ω_en)×δv − (2δω_ie+δω_en)×v + δg^n   (Mva, Mvv, Mvp)
    δL̇ = δvN/(R_M+h) − vN/(R_M+h)² (R_M' δL + δh)
    δλ̇ = δvE/((R_N+h)cosL) + vE tanL/((R_N+h)cosL) δL − vE/((R_N+h)² cosL)(R_N' δL + δh)
    δḣ = δvU                                                          (Mpv, Mpp)

``R_M' = dR_M/dL``, ``R_N' = dR_N/dL`` and ``∂g/∂L`` are kept when ``radius_derivatives=True``
(the default: the F is then the exact Jacobian of the mechanization equations with
sinslab's Earth model; PSINS drops them, a relative effect of order e² ≈ 0.007 on a few
position-coupling terms). ``δg^n = [0, 0, −(∂g/∂L δL + ∂g/∂h δh)]``.

Model building blocks
---------------------
A model = a *core* (which navigation errors are states) + *sensor blocks*:

========================  =====================================================
core                      states
========================  =====================================================
``"full"``                φ (3), δv (3), δp = [δL, δλ, δh] (9)
``"horizontal"``          φ (3), δvE, δvN, δL, δλ (7): vertical channel held
``"attvel"``              φ (3), δv (3) (6): position externally known (transfer alignment)
``"attvel-horizontal"``   φ (3), δvE, δvN (5)
``"attitude"``            φ (3)
========================  =====================================================

Sensor blocks (:func:`gyro_bias`, :func:`accel_bias`, :func:`gyro_markov`,
:func:`accel_markov`, :func:`gyro_scale`, :func:`accel_scale`, :func:`installation`) add
states with their own dynamics and a linear map into ``δω_ib^b`` or ``δf^b``. The
:class:`DifferenceModel` models ``INS 1 − INS k`` for two INS on one carrier.

All builders are vectorised: a :class:`NavPoint` whose fields have a leading shape ``S``
gives ``F`` of shape ``S + (n, n)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from sinslab.core import units
from sinslab.core.attitude import euler_to_dcm, skew
from sinslab.core.earth import A, DGDH, E2, G_EQ, K_SOM, WIE, gravity

__all__ = [
    "Block", "StateLayout", "NavPoint", "SensorBlock", "gyro_bias", "accel_bias",
    "gyro_markov", "accel_markov", "gyro_scale", "accel_scale", "installation",
    "ErrorModel", "DifferenceModel", "core_matrices",
    "CORES", "lever_arm", "odometer_scale", "ClockBlock", "receiver_clock", "COMPENSATIONS",
    "barometer_bias", "magnetometer_bias", "MeasurementStates", "carrier_ambiguities", "phase_clones",
    "fix_position_error",
]

#: The compensations of a strapdown INS a sensor block can feed (:attr:`Block.feeds`):
#: gyro and accelerometer bias [rad/s], [m/s²] and scale factors [-], body axes.
COMPENSATIONS = ("gyro_bias", "accel_bias", "gyro_scale", "accel_scale")

# ----------------------------------------------------------------------------- layout
_DISPLAY = {  # unit name -> SI value of one display unit
    "arcmin": units.arcmin, "arcsec": units.arcsec, "m/s": 1.0, "m": 1.0, "deg/h": units.dph,
    "ug": units.ug, "ppm": units.ppm, "rad": 1.0, "-": 1.0, "deg": units.deg, "uT": 1e-6, "cycle": 1.0,
}


@dataclass(frozen=True)
class Block:
    """A named group of consecutive states.

    Attributes
    ----------
    name : str
        Block name (``"phi"``, ``"dv"``, ``"dp"``, ``"eps"``, ...).
    labels : tuple of str
        One label per state (``"phiE"``, ``"dvN"``, ``"eps_x"``...), unique in a layout.
    units : tuple of str
        Display unit per state (``"arcmin"``, ``"m/s"``, ``"deg/h"``, ``"ug"``, ``"ppm"``,
        ``"arcsec"``, ``"m"``); states are SI inside, the unit is for printing only.
    feeds : {"gyro_bias", "accel_bias", "gyro_scale", "accel_scale", None}
        Which INS compensation (:data:`COMPENSATIONS`) a closed loop feeds the block's
        estimate into (body-axis sensor blocks); None: not a sensor compensation (core
        blocks, installation, lever arms, nav-frame biases, measurement-only states).
    axes : str
        Body axes of the states for a block with ``feeds`` (subset of ``"xyz"``).
    quantity : str or None
        What the states of a block that feeds nothing are, for the measurements that read
        them (:meth:`StateLayout.find`): ``"lever_arm"``, ``"odometer_scale"``,
        ``"installation"``, ``"receiver_clock"``, ``"baro_bias"``, ``"mag_hard_iron"``; None
        for the others.
    """

    name: str
    labels: tuple
    units: tuple
    feeds: str | None = None
    axes: str = ""
    quantity: str | None = None

    def __post_init__(self):
        if len(self.labels) != len(self.units):
            raise ValueError(f"block {self.name!r}: {len(self.labels)} labels, {len(self.units)} units")

    @property
    def size(self) -> int:
        return len(self.labels)


class StateLayout:
    """Ordered named blocks of an error-state vector, with slices and display units.

    Parameters
    ----------
    blocks : sequence of Block
        In state order.

    Examples
    --------
    >>> lay = ErrorModel("full", [gyro_bias(), accel_bias()]).layout
    >>> lay.n, lay.slice("eps"), lay.index("dvN")
    (15, slice(9, 12, None), 4)
    """

    def __init__(self, blocks: Sequence[Block]):
        self.blocks = tuple(blocks)
        names = [b.name for b in self.blocks]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate block names in {names}")
        self.labels = tuple(l for b in self.blocks for l in b.labels)
        if len(set(self.labels)) != len(self.labels):
            raise ValueError(f"duplicate state labels in {self.labels}")
        self.units = tuple(u for b in self.blocks for u in b.units)
        self.n = len(self.labels)
        self._slices = {}
        i = 0
        for b in self.blocks:
            self._slices[b.name] = slice(i, i + b.size)
            i += b.size

    @property
    def names(self):
        """Block names in order."""
        return tuple(b.name for b in self.blocks)

    def slice(self, name: str) -> slice:
        """Slice of block ``name`` in the state vector."""
        try:
            return self._slices[name]
        except KeyError:
            raise KeyError(f"no block {name!r}; blocks are {self.names}") from None

    def find(self, quantity, name=None):
        """Slice of the block of ``quantity`` (:attr:`Block.quantity`), or None when the
        layout has none; ``name`` picks one of several such blocks (two lever arms).

        Raises
        ------
        ValueError
            Several blocks of ``quantity`` and no ``name``, or block ``name`` is not one.
        """
        blocks = [b.name for b in self.blocks if b.quantity == quantity]
        if name is not None:
            if name not in blocks:
                raise ValueError(f"the layout has no {quantity} block {name!r} (has {blocks})")
            return self.slice(name)
        if len(blocks) > 1:
            raise ValueError(f"the layout has several {quantity} blocks {blocks}: name the one to use")
        return self.slice(blocks[0]) if blocks else None

    def index(self, label):
        """Index of a state label, or array of indices for a list of labels."""
        if isinstance(label, str):
            try:
                return self.labels.index(label)
            except ValueError:
                raise KeyError(f"no state {label!r}; states are {self.labels}") from None
        return np.array([self.index(l) for l in label], dtype=int)

    def selector(self, labels) -> np.ndarray:
        """Selection matrix ``H`` (len(labels), n) with ``H x = x[labels]``."""
        idx = self.index(list(labels))
        H = np.zeros((idx.size, self.n))
        H[np.arange(idx.size), idx] = 1.0
        return H

    @property
    def display_scale(self) -> np.ndarray:
        """SI value of one display unit per state, shape (n,): ``x / display_scale``."""
        return np.array([_DISPLAY[u] for u in self.units])

    def to_display(self, x):
        """State vector(s) (..., n) in display units."""
        return np.asarray(x, dtype=float) / self.display_scale

    def format(self, x, digits: int = 4) -> str:
        """One line per state: label, value in its display unit."""
        xd = self.to_display(x)
        return "\n".join(f"{l:>10s} {v: .{digits}g} {u}" for l, v, u in zip(self.labels, xd, self.units))

    def __repr__(self):
        return "StateLayout(" + ", ".join(f"{b.name}[{b.size}]" for b in self.blocks) + ")"


# ------------------------------------------------------------------------- nav sample
@dataclass(frozen=True)
class NavPoint:
    """Navigation state (true or best estimate) at which F and G are evaluated.

    All fields broadcast to a common leading shape ``S`` (empty for one epoch).

    Attributes
    ----------
    lat : array_like, shape S
        Latitude [rad].
    h : array_like, shape S
        Height [m].
    vel : array_like, shape S + (3,)
        Velocity ENU [m/s].
    Cbn : array_like, shape S + (3, 3)
        Attitude ``C_b^n`` of the IMU body frame.
    fb : array_like, shape S + (3,)
        Specific force in body axes [m/s²].
    wb : array_like, shape S + (3,)
        Angular rate ω_ib^b [rad/s] (needed by gyro scale-factor states only).
    """

    lat: np.ndarray
    h: np.ndarray
    vel: np.ndarray
    Cbn: np.ndarray
    fb: np.ndarray
    wb: np.ndarray = None

    def __post_init__(self):
        lat = np.asarray(self.lat, dtype=float)
        h = np.asarray(self.h, dtype=float)
        vel = np.asarray(self.vel, dtype=float)
        C = np.asarray(self.Cbn, dtype=float)
        fb = np.asarray(self.fb, dtype=float)
        wb = np.zeros(3) if self.wb is None else np.asarray(self.wb, dtype=float)
        for name, a, tail in (("vel", vel, (3,)), ("Cbn", C, (3, 3)), ("fb", fb, (3,)), ("wb", wb, (3,))):
            if a.shape[a.ndim - len(tail):] != tail:
                raise ValueError(f"NavPoint.{name} must end with shape {tail}, got {a.shape}")
        S = np.broadcast_shapes(lat.shape, h.shape, vel.shape[:-1], C.shape[:-2], fb.shape[:-1],
                                wb.shape[:-1])
        for name, a, tail in (("lat", lat, ()), ("h", h, ()), ("vel", vel, (3,)), ("Cbn", C, (3, 3)),
                              ("fb", fb, (3,)), ("wb", wb, (3,))):
            a = np.broadcast_to(a, S + tail)
            if not np.all(np.isfinite(a)):
                raise ValueError(f"NavPoint.{name} has non-finite values")
            object.__setattr__(self, name, a)
        if np.any(np.abs(lat) >= np.pi / 2):
            raise ValueError("NavPoint latitude must be inside (-90, 90) deg")

    @property
    def shape(self):
        """Leading shape ``S``."""
        return self.lat.shape

    @property
    def fn(self):
        """Specific force in n, ``C_b^n f^b`` [m/s²], shape S + (3,)."""
        return np.einsum("...ij,...j->...i", self.Cbn, self.fb)

    def __getitem__(self, idx):
        return NavPoint(self.lat[idx], self.h[idx], self.vel[idx], self.Cbn[idx], self.fb[idx], self.wb[idx])

    def with_attitude(self, Cbn, fb=None, wb=None):
        """Same carrier position/velocity, another body frame (e.g. a second IMU).

        ``fb``/``wb`` default to the same specific force / rate in n re-expressed in
        the new body axes (a mount whose own rotation rate is not included).
        """
        Cbn = np.asarray(Cbn, dtype=float)
        if fb is None:
            fb = np.einsum("...ji,...j->...i", Cbn, self.fn)
        if wb is None:
            wb = np.einsum("...ji,...j->...i", Cbn, np.einsum("...ij,...j->...i", self.Cbn, self.wb))
        return NavPoint(self.lat, self.h, self.vel, Cbn, fb, wb)

    @classmethod
    def static(cls, lat, att=(0.0, 0.0, 0.0), h=0.0):
        """A stationary point: v = 0, ``f^n = [0, 0, g]``, ``ω_ib^n = ω_ie^n``.

        Parameters
        ----------
        lat : float or array
            Latitude [rad].
        att : array_like (..., 3) or (3, 3) DCM
            ``[pitch, roll, yaw]`` [rad] of the IMU, or ``C_b^n`` itself.
        h : float
            Height [m].
        """
        att = np.asarray(att, dtype=float)
        C = att if att.shape[-2:] == (3, 3) else euler_to_dcm(att)
        lat = np.asarray(lat, dtype=float)
        g = gravity(lat, h)
        fn = np.stack(np.broadcast_arrays(0.0 * g, 0.0 * g, g), -1)
        wn = np.stack(np.broadcast_arrays(0.0 * lat, WIE * np.cos(lat), WIE * np.sin(lat)), -1)
        fb = np.einsum("...ji,...j->...i", C, fn)
        wb = np.einsum("...ji,...j->...i", C, wn)
        return cls(lat, h, np.zeros(3), C, fb, wb)

    @classmethod
    def from_series(cls, series, imu=None, idx=None, imu_frame=True):
        """Nav points at the epochs of a :class:`sinslab.core.records.NavSeries`.

        Parameters
        ----------
        series : NavSeries
            M epochs (truth or navigation solution).
        imu : ImuRecord, optional
            Increments on the same grid (N = M − 1 samples); epoch k ≥ 1 uses sample k − 1's
            mean rates, epoch 0 uses sample 0. Without it ``fb`` is the level static value and
            ``wb`` the Earth rate (a rough approximation for slow vehicles).
        idx : index, optional
            Epochs to take (slice, mask or indices); default all.
        imu_frame : bool
            Use ``series.att_imu`` when present (the IMU body frame), else ``series.att``.
        """
        from sinslab.core.attitude import euler_to_dcm as e2d
        sel = slice(None) if idx is None else idx
        att = series.att_imu if (imu_frame and series.att_imu is not None) else series.att
        C = e2d(att[sel])
        lat = series.lat[sel]
        if imu is None:
            st = cls.static(lat, C, series.h[sel])
            return cls(lat, series.h[sel], series.vel[sel], C, st.fb, st.wb)
        k = np.arange(series.t.size)[sel]
        j = np.clip(k - 1, 0, len(imu) - 1)
        fb = imu.dv[j] / imu.dt
        wb = imu.dtheta[j] / imu.dt
        return cls(lat, series.h[sel], series.vel[sel], C, fb, wb)


# --------------------------------------------------------------------------- the core
def core_matrices(nav: NavPoint, radius_derivatives: bool = True):
    """The 9×9 navigation-error matrix of the full core and the 3 body-input maps.

    Parameters
    ----------
    nav : NavPoint
        Leading shape S.
    radius_derivatives : bool
        Keep dR_M/dL, dR_N/dL and ∂g/∂L terms (exact Jacobian); PSINS drops them.

    Returns
    -------
    Fc : ndarray, shape S + (9, 9)
        Rows/columns ``[φE φN φU, δvE δvN δvU, δL δλ δh]``.
    Cbn : ndarray, shape S + (3, 3)
        ``C_b^n``: ``φ̇ += −C_b^n δω_ib^b``, ``δv̇ += C_b^n δf^b``.
    """
    L, h, v = nav.lat, nav.h, nav.vel
    S = L.shape
    sL, cL = np.sin(L), np.cos(L)
    tL = sL / cL
    q = 1.0 - E2 * sL * sL
    RM0 = A * (1.0 - E2) / q ** 1.5
    RN0 = A / np.sqrt(q)
    RMh, RNh = RM0 + h, RN0 + h
    if radius_derivatives:
        dRM = RM0 * 3.0 * E2 * sL * cL / q
        dRN = RN0 * E2 * sL * cL / q
        dgdL = G_EQ * (2.0 * K_SOM * sL * cL / np.sqrt(q) + (1.0 + K_SOM * sL * sL) * E2 * sL * cL / q ** 1.5)
    else:
        dRM = dRN = dgdL = np.zeros(S)
    vE, vN = v[..., 0], v[..., 1]
    z = np.zeros(S)
    wie = np.stack([z, WIE * cL, WIE * sL], -1)
    wen = np.stack([-vN / RMh, vE / RNh, vE * tL / RNh], -1)
    win = wie + wen
    Mav = np.zeros(S + (3, 3))
    Mav[..., 0, 1] = -1.0 / RMh
    Mav[..., 1, 0] = 1.0 / RNh
    Mav[..., 2, 0] = tL / RNh
    M1 = np.zeros(S + (3, 3))                      # ∂ω_ie/∂p
    M1[..., 1, 0] = -WIE * sL
    M1[..., 2, 0] = WIE * cL
    M2 = np.zeros(S + (3, 3))                      # ∂ω_en/∂p
    M2[..., 0, 0] = vN * dRM / RMh ** 2
    M2[..., 0, 2] = vN / RMh ** 2
    M2[..., 1, 0] = -vE * dRN / RNh ** 2
    M2[..., 1, 2] = -vE / RNh ** 2
    M2[..., 2, 0] = vE / (cL * cL * RNh) - vE * tL * dRN / RNh ** 2
    M2[..., 2, 2] = -vE * tL / RNh ** 2
    vx = skew(v)
    Fc = np.zeros(S + (9, 9))
    Fc[..., 0:3, 0:3] = -skew(win)
    Fc[..., 0:3, 3:6] = Mav
    Fc[..., 0:3, 6:9] = M1 + M2
    Fc[..., 3:6, 0:3] = skew(nav.fn)
    Fc[..., 3:6, 3:6] = vx @ Mav - skew(2.0 * wie + wen)
    Fc[..., 3:6, 6:9] = vx @ (2.0 * M1 + M2)
    Fc[..., 5, 6] += -dgdL
    Fc[..., 5, 8] += DGDH                          # δg_U = −∂g/∂h δh, ∂g/∂h = −DGDH
    Fc[..., 6, 4] = 1.0 / RMh
    Fc[..., 6, 6] = -vN * dRM / RMh ** 2
    Fc[..., 6, 8] = -vN / RMh ** 2
    Fc[..., 7, 3] = 1.0 / (RNh * cL)
    Fc[..., 7, 6] = vE * tL / (RNh * cL) - vE * dRN / (RNh ** 2 * cL)
    Fc[..., 7, 8] = -vE / (RNh ** 2 * cL)
    Fc[..., 8, 5] = 1.0
    return Fc, nav.Cbn


_CORE_LABELS = ("phiE", "phiN", "phiU", "dvE", "dvN", "dvU", "dL", "dlam", "dh")
_CORE_UNITS = ("arcmin",) * 3 + ("m/s",) * 3 + ("arcsec", "arcsec", "m")
#: core name -> indices of the kept states among the 9 of the full core
CORES = {
    "full": (0, 1, 2, 3, 4, 5, 6, 7, 8),
    "horizontal": (0, 1, 2, 3, 4, 6, 7),
    "attvel": (0, 1, 2, 3, 4, 5),
    "attvel-horizontal": (0, 1, 2, 3, 4),
    "attitude": (0, 1, 2),
}


def _core_blocks(core, suffix=""):
    keep = CORES[core]
    blocks = []
    for name, rng in (("phi", range(0, 3)), ("dv", range(3, 6)), ("dp", range(6, 9))):
        idx = [i for i in rng if i in keep]
        if idx:
            blocks.append(Block(name, tuple(_CORE_LABELS[i] + suffix for i in idx),
                                tuple(_CORE_UNITS[i] for i in idx)))
    return blocks


# ----------------------------------------------------------------------- sensor blocks
_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class SensorBlock:
    """States describing sensor (or installation) errors.

    Use the constructors :func:`gyro_bias`, :func:`accel_bias`, :func:`gyro_markov`,
    :func:`accel_markov`, :func:`gyro_scale`, :func:`accel_scale`, :func:`installation`.

    Attributes
    ----------
    name : str
        Block name (labels are ``name + "_" + axis``).
    sensor : {"gyro", "accel", None}
        Which input error the states drive (``δω_ib`` or ``δf``); None: no coupling
        (random constants seen only by measurements, e.g. installation angles).
    kind : {"bias", "markov", "scale", "constant"}
        ``bias``: the states are added to the sensor output (``δω = x``); ``markov``: same
        coupling, dynamics ``ẋ = −x/τ + w``; ``scale``: ``δω = diag(ω^b) x`` /
        ``δf = diag(f^b) x`` (dynamics ``ẋ = −x/τ + w`` when ``tau`` is set, else a random
        constant or walk); ``constant``: no coupling.
    axes : str
        Sensor axes carried, a subset of ``"xyz"`` in order (``"xy"``: horizontal
        accelerometers only).
    frame : {"body", "nav"}
        ``nav``: the states are already in n (paper 000's ε^n, ∇^n): coupling without C_b^n.
    tau : float or None
        Correlation time [s] for ``markov``.
    q : ndarray, shape (k,)
        Spectral density of each state's driving noise (0 = random constant).
    unit : str
        Display unit.
    quantity : str or None
        See :attr:`Block.quantity` (blocks with no coupling that measurements read).
    """

    name: str
    sensor: str | None
    kind: str
    axes: str = "xyz"
    frame: str = "body"
    tau: float | None = None
    q: np.ndarray = field(default=None)
    unit: str = "-"
    quantity: str | None = None

    def __post_init__(self):
        if not self.axes or any(a not in _AXES for a in self.axes) or len(set(self.axes)) != len(self.axes):
            raise ValueError(f"block {self.name!r}: axes must be a subset of 'xyz', got {self.axes!r}")
        if self.frame not in ("body", "nav"):
            raise ValueError(f"block {self.name!r}: frame must be 'body' or 'nav'")
        if self.kind == "markov" and not (self.tau and self.tau > 0):
            raise ValueError(f"block {self.name!r}: Gauss-Markov correlation time must be > 0, got {self.tau}")
        q = np.zeros(len(self.axes)) if self.q is None else np.broadcast_to(
            np.asarray(self.q, dtype=float), (len(self.axes),)).copy()
        if np.any(q < 0) or not np.all(np.isfinite(q)):
            raise ValueError(f"block {self.name!r}: noise densities must be finite and >= 0")
        object.__setattr__(self, "q", q)

    @property
    def size(self):
        return len(self.axes)

    def block(self, suffix="") -> Block:
        ax = self.axes if self.frame == "body" else "".join("ENU"[_AXES[a]] for a in self.axes)
        return Block(self.name + suffix, tuple(f"{self.name}_{a}{suffix}" for a in ax), (self.unit,) * self.size,
                     self.feeds, self.axes, self.quantity)

    @property
    def feeds(self):
        """The INS compensation the states correct (see :attr:`Block.feeds`): a body-axis
        gyro/accelerometer ``bias`` or ``markov`` block feeds the bias compensation, a
        ``scale`` block the scale-factor compensation; anything else feeds nothing."""
        if self.sensor not in ("gyro", "accel") or self.frame != "body":
            return None
        if self.kind in ("bias", "markov"):
            return self.sensor + "_bias"
        if self.kind == "scale":
            return self.sensor + "_scale"
        return None

    def coupling(self, nav: NavPoint) -> np.ndarray:
        """Map ``S + (3, k)`` from the block's states to ``δω_ib^b`` or ``δf^b``."""
        idx = [_AXES[a] for a in self.axes]
        S = nav.shape
        M = np.zeros(S + (3, self.size))
        if self.kind in ("bias", "markov"):
            M[..., idx, np.arange(self.size)] = 1.0
        elif self.kind == "scale":
            src = nav.wb if self.sensor == "gyro" else nav.fb
            M[..., idx, np.arange(self.size)] = src[..., idx]
        return M

    def dynamics(self) -> np.ndarray:
        """Diagonal of the block's own dynamics matrix, shape (k,)."""
        if self.kind == "markov" or (self.kind == "scale" and self.tau):
            return np.full(self.size, -1.0 / self.tau)
        return np.zeros(self.size)


def gyro_bias(axes="xyz", rrw=0.0, frame="body", name="eps"):
    """Gyro bias ε [rad/s]: random constant, or random walk with density ``rrw²``.

    ``rrw`` is the rate random walk [rad/s/√s] (scalar or per axis).
    """
    return SensorBlock(name, "gyro", "bias", axes, frame, None, np.asarray(rrw, float) ** 2, "deg/h")


def accel_bias(axes="xyz", arw=0.0, frame="body", name="nabla"):
    """Accelerometer bias ∇ [m/s²]: random constant, or random walk (``arw`` [m/s²/√s])."""
    return SensorBlock(name, "accel", "bias", axes, frame, None, np.asarray(arw, float) ** 2, "ug")


def _check_tau(tau, name):
    tau = float(tau)
    if not (np.isfinite(tau) and tau > 0):
        raise ValueError(f"block {name!r}: Gauss-Markov correlation time must be > 0, got {tau}")
    return tau


def gyro_markov(tau, sigma, axes="xyz", frame="body", name="eps_m"):
    """First-order Gauss–Markov gyro drift: ``ẋ = −x/τ + w``, q = 2σ²/τ (σ steady-state [rad/s])."""
    tau = _check_tau(tau, name)
    return SensorBlock(name, "gyro", "markov", axes, frame, float(tau),
                       2.0 * np.asarray(sigma, float) ** 2 / float(tau), "deg/h")


def accel_markov(tau, sigma, axes="xyz", frame="body", name="nabla_m"):
    """First-order Gauss–Markov accelerometer bias, q = 2σ²/τ (σ [m/s²], τ [s])."""
    tau = _check_tau(tau, name)
    return SensorBlock(name, "accel", "markov", axes, frame, float(tau),
                       2.0 * np.asarray(sigma, float) ** 2 / float(tau), "ug")


def _scale_noise(rw, tau, sigma, name):
    """(τ or None, q) of a scale-factor or barometer-bias block: random constant, random
    walk (``rw`` [unit/√s]) or first-order Gauss–Markov (``tau`` [s], steady-state
    ``sigma`` [unit])."""
    if tau is None:
        if sigma is not None:
            raise ValueError(f"block {name!r}: a Gauss-Markov sigma needs its correlation time tau")
        return None, np.asarray(rw, float) ** 2
    if np.any(np.asarray(rw, float) != 0):
        raise ValueError(f"block {name!r}: give a random walk or a Gauss-Markov process, not both")
    tau = _check_tau(tau, name)
    return tau, 2.0 * np.asarray(0.0 if sigma is None else sigma, float) ** 2 / tau


def gyro_scale(axes="xyz", name="kg", rw=0.0, tau=None, sigma=None):
    """Gyro scale-factor errors (diagonal) [-]: ``δω_ib^b = diag(ω_ib^b) k_g``; a random
    constant, a random walk (``rw`` [1/√s]) or a Gauss–Markov process (``tau`` [s],
    steady-state ``sigma`` [-], ``k̇ = −k/τ + w``, q = 2σ²/τ)."""
    tau, q = _scale_noise(rw, tau, sigma, name)
    return SensorBlock(name, "gyro", "scale", axes, "body", tau, q, "ppm")


def accel_scale(axes="xyz", name="ka", rw=0.0, tau=None, sigma=None):
    """Accelerometer scale-factor errors (diagonal) [-]: ``δf^b = diag(f^b) k_a``; random
    constant, random walk or Gauss–Markov as :func:`gyro_scale`."""
    tau, q = _scale_noise(rw, tau, sigma, name)
    return SensorBlock(name, "accel", "scale", axes, "body", tau, q, "ppm")


def installation(name="lam", axes="xyz"):
    """Installation (master–slave misalignment) angles [rad], random constant.

    They have no dynamics and no effect on the INS error propagation; measurement models
    (attitude matching, paper 002: ``φ_m = λ − C φ``) read them.
    """
    return SensorBlock(name, None, "constant", axes, "body", None, None, "arcmin", "installation")


# ------------------------------------------------------------------------------ models
def _noise_columns(axes, sensor, suffix):
    return [f"w{sensor}_{a}{suffix}" for a in axes]


class ErrorModel:
    """Continuous error-state model ``ẋ = F x + G w`` of one INS.

    Parameters
    ----------
    core : str
        One of :data:`CORES` (``"full"``, ``"horizontal"``, ``"attvel"``,
        ``"attvel-horizontal"``, ``"attitude"``).
    sensors : sequence of SensorBlock
        Extra states, in order after the core.
    gyro_arw : float or (3,)
        Gyro white noise (angle random walk) [rad/√s]; q = gyro_arw².
    accel_vrw : float or (3,)
        Accelerometer white noise (velocity random walk) [m/s/√s]; q = accel_vrw².
    gyro_arw_axes, accel_vrw_axes : str
        Body axes that carry white noise (default all three).
    order : sequence of str, optional
        Block order (names); default core then sensors.
    radius_derivatives : bool
        Keep the dR/dL and ∂g/∂L terms (exact Jacobian). See module docstring.

    Attributes
    ----------
    layout : StateLayout
    noise_labels : tuple of str
        Names of the columns of G.
    q : ndarray (m,)
        Spectral densities of w (SI).

    Notes
    -----
    ``F(nav)`` and ``G(nav)`` accept a :class:`NavPoint` of leading shape S and return
    ``S + (n, n)`` / ``S + (n, m)``.
    """

    def __init__(self, core="full", sensors: Sequence[SensorBlock] = (), gyro_arw=0.0, accel_vrw=0.0,
                 gyro_arw_axes="xyz", accel_vrw_axes="xyz", order=None, radius_derivatives=True):
        if core not in CORES:
            raise ValueError(f"unknown core {core!r}; choose from {list(CORES)}")
        self.core = core
        self.radius_derivatives = radius_derivatives
        self._ins = [dict(sensors=tuple(sensors), sign=1.0, suffix="",
                          gnoise=self._noise(gyro_arw, gyro_arw_axes), gaxes=gyro_arw_axes,
                          anoise=self._noise(accel_vrw, accel_vrw_axes), aaxes=accel_vrw_axes)]
        self._finish(order)

    # -- construction helpers
    @staticmethod
    def _noise(val, axes):
        a = np.broadcast_to(np.asarray(val, dtype=float), (len(axes),)).copy()
        if np.any(a < 0) or not np.all(np.isfinite(a)):
            raise ValueError("white-noise densities must be finite and >= 0")
        return a

    def _finish(self, order):
        sfx = self._ins[0]["suffix"] if len(self._ins) == 1 else self._core_suffix
        blocks = _core_blocks(self.core, sfx)
        self._core_names = [b.name for b in blocks]
        for ins in self._ins:
            for s in ins["sensors"]:
                blocks.append(s.block(ins["suffix"]))
        by_name = {b.name: b for b in blocks}
        if order is not None:
            order = list(order)
            if sorted(order) != sorted(by_name):
                raise ValueError(f"order {order} must list exactly the blocks {list(by_name)}")
            blocks = [by_name[o] for o in order]
        self.layout = StateLayout(blocks)
        # noise columns: per INS gyro white, accel white, then sensor-block driving noises
        labels, q = [], []
        for ins in self._ins:
            labels += _noise_columns(ins["gaxes"], "g", ins["suffix"])
            q.append(ins["gnoise"] ** 2)
            labels += _noise_columns(ins["aaxes"], "a", ins["suffix"])
            q.append(ins["anoise"] ** 2)
        for ins in self._ins:
            for s in ins["sensors"]:
                if np.any(s.q > 0):
                    labels += [f"w_{l}" for l in s.block(ins["suffix"]).labels]
                    q.append(s.q)
        self.noise_labels = tuple(labels)
        self.q = np.concatenate(q) if q else np.zeros(0)

    @property
    def n(self):
        """Number of states."""
        return self.layout.n

    @property
    def white_noise(self):
        """``(gyro_arw (3,), accel_vrw (3,))`` of the INS [rad/√s], [m/s/√s] (zero on an
        axis without white noise)."""
        ins = self._ins[0]
        g, a = np.zeros(3), np.zeros(3)
        g[[_AXES[c] for c in ins["gaxes"]]] = ins["gnoise"]
        a[[_AXES[c] for c in ins["aaxes"]]] = ins["anoise"]
        return g, a

    @property
    def sensor_blocks(self):
        """The sensor blocks of the INS, in the order given."""
        return self._ins[0]["sensors"]

    def __repr__(self):
        return f"{type(self).__name__}(core={self.core!r}, {self.layout!r}, noises={len(self.q)})"

    # -- assembly
    def _rows(self):
        """Positions (in the model's state vector) of the kept core states, per full-core index."""
        keep = CORES[self.core]
        rows = {}
        lab = self.layout.labels
        sfx = "" if len(self._ins) == 1 else self._core_suffix
        for i in keep:
            rows[i] = lab.index(_CORE_LABELS[i] + sfx)
        return rows

    def _assemble(self, navs, core_nav):
        n = self.n
        S = core_nav.shape
        Fc, _ = core_matrices(core_nav, self.radius_derivatives)
        rows = self._rows()
        ki = np.array(list(rows.keys()))
        ri = np.array(list(rows.values()))
        F = np.zeros(S + (n, n))
        F[..., ri[:, None], ri[None, :]] = Fc[..., ki[:, None], ki[None, :]]
        m = len(self.q)
        G = np.zeros(S + (n, m))
        att_k = [k for k in ki if k < 3]
        vel_k = [k for k in ki if 3 <= k < 6]
        att_r = np.array([rows[k] for k in att_k], dtype=int)
        vel_r = np.array([rows[k] for k in vel_k], dtype=int)
        vel_k = np.array(vel_k, dtype=int) - 3
        col = 0
        for ins, nav in zip(self._ins, navs):
            C = nav.Cbn
            sg = ins["sign"]
            gi = [_AXES[a] for a in ins["gaxes"]]
            G[..., att_r[:, None], col + np.arange(len(gi))[None, :]] = -sg * C[..., np.array(att_k)[:, None], np.array(gi)[None, :]]
            col += len(gi)
            ai = [_AXES[a] for a in ins["aaxes"]]
            if vel_r.size:
                G[..., vel_r[:, None], col + np.arange(len(ai))[None, :]] = sg * C[..., vel_k[:, None], np.array(ai)[None, :]]
            col += len(ai)
            for s in ins["sensors"]:
                if s.sensor is None:
                    continue
                sl = self.layout.slice(s.name + ins["suffix"])
                M = s.coupling(nav)                       # S + (3, k)
                if s.frame == "body":
                    M = C @ M
                if s.sensor == "gyro":
                    F[..., att_r[:, None], np.arange(sl.start, sl.stop)[None, :]] = -sg * M[..., att_k, :]
                elif vel_r.size:
                    F[..., vel_r[:, None], np.arange(sl.start, sl.stop)[None, :]] = sg * M[..., vel_k, :]
        for ins in self._ins:
            for s in ins["sensors"]:
                sl = self.layout.slice(s.name + ins["suffix"])
                d = s.dynamics()
                if d.ndim == 2:           # a block with coupled states (receiver clock)
                    F[..., sl, sl] = d
                else:
                    F[..., np.arange(sl.start, sl.stop), np.arange(sl.start, sl.stop)] = d
                if np.any(s.q > 0):
                    G[..., np.arange(sl.start, sl.stop), col + np.arange(s.size)] = 1.0
                    col += s.size
        return F, G

    def matrices(self, nav: NavPoint):
        """``(F, G)`` at ``nav``: shapes ``S + (n, n)`` and ``S + (n, m)``."""
        return self._assemble([nav], nav)

    def F(self, nav: NavPoint) -> np.ndarray:
        """System matrix F [1/s or mixed SI], shape ``S + (n, n)``."""
        return self.matrices(nav)[0]

    def G(self, nav: NavPoint) -> np.ndarray:
        """Noise input matrix G, shape ``S + (n, m)`` (columns: :attr:`noise_labels`)."""
        return self.matrices(nav)[1]

    def Qc(self, nav: NavPoint) -> np.ndarray:
        """Continuous process-noise density ``G diag(q) Gᵀ``, shape ``S + (n, n)``."""
        G = self.G(nav)
        return (G * self.q) @ np.swapaxes(G, -1, -2)


class DifferenceModel(ErrorModel):
    """Error model of the difference of two INS on one carrier: ``x = x_1 − x_k`` (core) +
    the sensor states of both.

    Both INS navigate the same carrier, so the core dynamics (which depend on position,
    velocity and ``f^n``) are common and the core states are the differences
    ``δp_1 − δp_k``, ``δv_1 − δv_k``, ``φ_1 − φ_k``. Each INS's sensor errors enter through
    its own ``C_b^n`` (different under indexing/rotation mechanisms), INS 1 with ``+`` and
    INS k with ``−``: the attitude rows get ``[−C_b1^n, +C_bk^n]`` on the gyro states and
    the velocity rows ``[+C_b1^n, −C_bk^n]`` on the accelerometer states.

    Parameters
    ----------
    core : str
        As in :class:`ErrorModel`.
    sensors1, sensorsk : sequences of SensorBlock
        Sensor states of INS 1 and INS k (block names get the suffixes).
    gyro_arw1, gyro_arwk, accel_vrw1, accel_vrwk : float or array
        White-noise densities of each INS [rad/√s], [m/s/√s].
    suffixes : (str, str)
        Appended to the sensor block names and labels, default ``("_1", "_k")``.
    core_suffix : str
        Appended to the difference core labels, default ``"_1k"``.

    Notes
    -----
    ``F(nav1, navk)``: ``nav1`` supplies the common position, velocity and ``f^n``; each
    nav supplies its own ``C_b^n`` (and ``f^b``, ``ω^b`` for scale-factor states).
    """

    def __init__(self, core="horizontal", sensors1=(), sensorsk=(), gyro_arw1=0.0, gyro_arwk=0.0,
                 accel_vrw1=0.0, accel_vrwk=0.0, gyro_arw_axes="xyz", accel_vrw_axes="xyz",
                 suffixes=("_1", "_k"), core_suffix="_1k", order=None, radius_derivatives=True):
        if core not in CORES:
            raise ValueError(f"unknown core {core!r}; choose from {list(CORES)}")
        self.core = core
        self.radius_derivatives = radius_derivatives
        self._core_suffix = core_suffix
        self._ins = []
        for sens, gn, an, sg, sfx in ((sensors1, gyro_arw1, accel_vrw1, 1.0, suffixes[0]),
                                      (sensorsk, gyro_arwk, accel_vrwk, -1.0, suffixes[1])):
            self._ins.append(dict(sensors=tuple(sens), sign=sg, suffix=sfx,
                                  gnoise=self._noise(gn, gyro_arw_axes), gaxes=gyro_arw_axes,
                                  anoise=self._noise(an, accel_vrw_axes), aaxes=accel_vrw_axes))
        self._finish(order)

    def _finish(self, order):
        # core blocks carry the difference suffix in labels, plain names
        super()._finish(order)

    def matrices(self, nav1: NavPoint, navk: NavPoint = None):
        """``(F, G)``: ``nav1`` gives the carrier state and C_b1^n, ``navk`` gives C_bk^n."""
        if navk is None:
            raise TypeError("DifferenceModel needs both nav1 and navk")
        return self._assemble([nav1, navk], nav1)

    def F(self, nav1, navk=None):
        return self.matrices(nav1, navk)[0]

    def G(self, nav1, navk=None):
        return self.matrices(nav1, navk)[1]

    def Qc(self, nav1, navk=None):
        G = self.G(nav1, navk)
        return (G * self.q) @ np.swapaxes(G, -1, -2)


# ------------------------------------------------------------- aiding-sensor blocks
def lever_arm(name="lev"):
    """Lever arm of an aiding sensor (e.g. a GNSS antenna) [m], body axes, random constant.

    The states are the error of the lever arm the measurement uses, computed minus true
    (``δl = l_used − l_true``); they have no dynamics, feed nothing back to the INS and are
    read by the lever-arm measurements of :mod:`sinslab.fusion.measurements`.
    """
    return SensorBlock(name, None, "constant", "xyz", "body", None, None, "m", "lever_arm")


def odometer_scale(name="kod"):
    """Odometer scale-factor error k [-], random constant, one state on the forward body
    axis y, defined by ``v_fwd = (1 − k) s̃`` for the wheel-speed reading ``s̃`` (so that
    the odometer measurement is exactly linear in k, see
    :class:`sinslab.fusion.measurements.Odometer`); a reading ``s̃ = (1 + k_s) v_fwd`` has
    ``k = k_s / (1 + k_s)``, equal to first order."""
    return SensorBlock(name, None, "constant", "y", "body", None, None, "ppm", "odometer_scale")


def barometer_bias(*, tau=None, sigma=None, rw=0.0, name="baro"):
    """Bias of a barometric altimeter [m]: the error of the bias the measurement removes,
    computed minus true (``δb = b_used − b_true``), one state (label ``<name>_U``).

    A random constant, a random walk (``rw`` [m/√s]) or a first-order Gauss–Markov
    process (``tau`` [s], steady-state ``sigma`` [m], ``ḃ = −b/τ + w``, q = 2σ²/τ), the
    slow drift of the pressure-height relation with weather and temperature. The state
    feeds nothing back to the INS; :class:`sinslab.fusion.measurements.Barometer` reads it.
    """
    tau, q = _scale_noise(rw, tau, sigma, name)
    return SensorBlock(name, None, "markov" if tau else "constant", "z", "nav", tau, q, "m", "baro_bias")


def magnetometer_bias(*, tau=None, sigma=None, rw=0.0, name="mag"):
    """Residual hard iron of a three-axis magnetometer [T], body axes: the error of the
    offset the measurement removes from the calibrated reading, computed minus true
    (``δβ = β_used − β_true``), three states (labels ``<name>_x`` .. ``<name>_z``).

    A random constant (a calibration error, the airframe's permanent magnetisation), a
    random walk (``rw`` [T/√s]) or a first-order Gauss–Markov process (``tau`` [s],
    steady-state ``sigma`` [T]: fields of slowly changing currents). The states feed
    nothing back to the INS; the magnetometer measurements of
    :class:`~sinslab.fusion.measurements.MagneticField` and :class:`~sinslab.fusion.measurements.MagneticHeading` read them.
    """
    tau, q = _scale_noise(rw, tau, sigma, name)
    return SensorBlock(name, None, "markov" if tau else "constant", "xyz", "body", tau, q, "uT",
                       "mag_hard_iron")


def fix_position_error(*, tau, sigma, name="fixerr"):
    """Time-correlated error of the position fixes [m], east, north, up: the fix minus the
    true antenna position, a first-order Gauss–Markov process per axis (``tau`` [s],
    steady-state ``sigma`` (3,) [m], ``ė = −e/τ + w``, q = 2σ²/τ) — multipath and
    atmosphere errors of a receiver's solution that last tens of seconds. Treated as white
    noise at several fixes a second they pull the INS velocity by their rate of change; as
    states the position fixes are read against them
    (:class:`sinslab.fusion.measurements.PositionFix` finds the block by its quantity
    ``"fix_error"``). The states feed nothing back to the INS."""
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), (3,)).copy()
    if not np.all(np.isfinite(sig)) or np.any(sig < 0):
        raise ValueError(f"block {name!r}: fix-error sigma must be finite and >= 0, got {sigma!r}")
    tau = _check_tau(tau, name)
    return SensorBlock(name, None, "markov", "xyz", "nav", tau, 2.0 * sig ** 2 / tau, "m", "fix_error")


@dataclass(frozen=True)
class ClockBlock:
    """GNSS receiver clock states in range units: bias ``b = c·δt_r`` [m], drift
    ``d = c·δṫ_r`` [m/s] and one inter-system bias [m] per further system.

    Dynamics ``ḃ = d + w_b``, ``ḋ = w_d``, inter-system biases ``ḃ_s = w_s``; the
    pseudorange of a satellite of system s reads ``b + b_s`` (``b`` alone for the first
    system), its range rate ``d``. The states are the receiver's, not the INS's: they
    feed nothing back (use them through the GNSS measurements of
    :mod:`sinslab.fusion.gnss`). Build with :func:`receiver_clock`.

    Attributes
    ----------
    name : str
    systems : tuple of str
        System letters; the first is the reference of the bias, each further one has an
        inter-system bias state ``<name>_isb_<letter>``.
    q : ndarray (k,)
        White-noise densities: bias [m²/s], drift [m²/s³], inter-system biases [m²/s].
    """

    name: str
    systems: tuple
    q: np.ndarray
    sensor = None
    kind = "clock"
    frame = "body"
    tau = None
    axes = ""
    feeds = None

    @property
    def size(self):
        return 1 + len(self.systems)

    def block(self, suffix="") -> Block:
        labels = (f"{self.name}_bias", f"{self.name}_drift") + tuple(
            f"{self.name}_isb_{s}" for s in self.systems[1:])
        return Block(self.name + suffix, tuple(l + suffix for l in labels),
                     ("m", "m/s") + ("m",) * (len(self.systems) - 1), quantity="receiver_clock")

    def dynamics(self) -> np.ndarray:
        """The block's own dynamics matrix (k, k): the bias integrates the drift."""
        d = np.zeros((self.size, self.size))
        d[0, 1] = 1.0
        return d


def receiver_clock(systems=("G",), *, bias_noise=0.1, drift_noise=0.1, isb_noise=1e-4, name="clk"):
    """A :class:`ClockBlock` for the satellites of ``systems`` (letters, first = reference).

    ``bias_noise`` [m/√s] (white frequency noise, √(h0/2)·c), ``drift_noise`` [m/s/√s]
    (random-walk frequency noise, √(2π² h₋₂)·c), ``isb_noise`` [m/√s] (slow wander of the
    inter-system biases). The defaults suit a temperature-compensated crystal of a
    consumer receiver (h0 ≈ 2e-19, h₋₂ ≈ 2e-20 give 0.1 m/√s and 0.19 m/s/√s at most)."""
    systems = tuple(systems)
    if not systems or len(set(systems)) != len(systems):
        raise ValueError(f"receiver_clock: systems must be distinct letters, got {systems!r}")
    q = np.array([bias_noise, drift_noise] + [isb_noise] * (len(systems) - 1), float) ** 2
    if not np.all(np.isfinite(q)):
        raise ValueError("receiver clock noise densities must be finite")
    return ClockBlock(name, systems, q)


@dataclass(frozen=True)
class MeasurementStates:
    """States that belong to a measurement, which re-initialises or copies them itself
    (through the driver's state transform, :meth:`sinslab.estimation.filter.KalmanFilter.transform`):
    no coupling to the INS, no dynamics, optional random-walk noise, fed back to nothing.

    Build with :func:`carrier_ambiguities` or :func:`phase_clones`.

    Attributes
    ----------
    name : str
    labels : tuple of str
        One per state (``<name>_<label>``).
    unit : str
    q : ndarray (k,)
        Random-walk densities [unit²/s].
    quantity : str
        What the measurements find the block by (:meth:`StateLayout.find`).
    """

    name: str
    labels: tuple
    unit: str
    q: np.ndarray
    quantity: str
    sensor = None
    kind = "constant"
    frame = "body"
    tau = None
    axes = ""
    feeds = None

    @property
    def size(self):
        return len(self.labels)

    def block(self, suffix="") -> Block:
        return Block(self.name + suffix, tuple(f"{self.name}_{lab}{suffix}" for lab in self.labels),
                     (self.unit,) * self.size, quantity=self.quantity)

    def dynamics(self) -> np.ndarray:
        """Diagonal of the block's own dynamics matrix (zeros), shape (k,)."""
        return np.zeros(self.size)


def carrier_ambiguities(slots, *, noise=1e-4, name="amb"):
    """Carrier-phase ambiguity states [cycles], ``slots`` of them: each holds the error of
    one signal's single-difference ambiguity while the signal is tracked, and is handed to
    another signal after it is lost (:class:`sinslab.fusion.carrier.AmbiguitySlots`).
    ``noise`` [cycles/√s] lets a held float ambiguity follow slow phase-bias wander
    (RTKLIB's default process noise of the bias states, 1e-4)."""
    slots = int(slots)
    if slots < 1:
        raise ValueError(f"carrier_ambiguities: at least one slot, got {slots}")
    if not (np.isfinite(noise) and noise >= 0):
        raise ValueError(f"carrier_ambiguities: noise must be finite and >= 0, got {noise!r}")
    return MeasurementStates(name, tuple(str(i) for i in range(slots)), "cycle", np.full(slots, float(noise) ** 2),
                             "ambiguity")


def phase_clones(name="clone"):
    """The errors of the antenna position (ECEF x, y, z [m]) and receiver clock bias [m]
    recorded at an epoch, twice (sets a and b, used in turn): time-differenced carrier
    phase compares the present with the epoch before through them (stochastic cloning;
    :class:`sinslab.fusion.tdcp.TimeDifferencedPhase`)."""
    labels = tuple(f"{c}{k}" for k in "ab" for c in ("x", "y", "z", "b"))
    return MeasurementStates(name, labels, "m", np.zeros(8), "phase_clone")
