"""How the position fixes of a record really err, from the record itself.

A receiver's position error is not white: multipath and the atmosphere move it by metres
over tens of seconds while its Doppler velocity stays good to centimetres per second. A
filter that takes 5 fixes a second with a white σ of 1 m believes their average to 0.1 m
within 2 s, follows the error's drift and carries its rate (0.1–0.5 m/s) in its velocity
into the next outage.

The error's time structure is measured against the fixes' own velocities: over a lag Δ
the position change minus the integrated velocity (trapezoid rule) is the change of the
position error minus the velocity error integrated. Per axis, with the position error a
white part σ_w plus a first-order Gauss–Markov part (σ_c, τ) and the velocity error a
first-order Gauss–Markov process of variance σ_v² and correlation time T (independent of
the position error), its mean square (the structure function) is::

    D(Δ) = 2σ_w² + 2σ_c² (1 − e^(−Δ/τ)) + q_v (Δ − T (1 − e^(−Δ/T))),   q_v = 2σ_v² T

the last term being the variance of a Gauss–Markov process integrated over Δ, the double
integral of its autocovariance ``σ_v² e^(−|s−u|/T)`` over ``[0, Δ]²``:
``2σ_v² T² (Δ/T − 1 + e^(−Δ/T))``. For
``Δ ≫ T`` it is the random walk ``q_v Δ`` (minus a constant): a Doppler velocity's errors
last seconds, so their integral grows like a random walk, whatever the σ the receiver
states. For ``Δ ≲ T`` it grows like ``σ_v² Δ²``: convex. Without it a random walk alone,
``q_v Δ``, is the only velocity term, and a structure function whose short lags bend up
with the velocity error's own correlation can only be fitted by taking the concave
Gauss–Markov position part out — a receiver whose velocity errors last seconds is then
fitted with no position error at all (``T → 0`` gives back the random walk: the grid of T
starts at 0).

**At rest** a receiver's position error is held (the multipath geometry is frozen and
static receivers hold their solution) and its velocity reads zero: over a stop neither
the position error nor the integrated velocity error moves. Pairs within a stop add zeros
to every lag and pairs across one see a lag the error did not evolve over, so a record
with long stops shows a structure function scaled down and bent where its error process
has none. The fixes taken at rest (:func:`at_rest`: a horizontal speed that cannot be told
from zero given its stated σ) are left out and the moving stretches joined: a lag is time
in motion. (For a receiver whose error does evolve at rest a pair across a stop is then
counted at a shorter lag than it spans: the structure function, which grows with the lag,
comes out larger, not smaller.)

σ_w², σ_c² and q_v are fitted by non-negative least squares (relative residuals) for each
(τ, T) of logarithmic grids up to half the longest lag, the pair of the smallest residual
(summed over the axes) kept. The filter then carries the Gauss–Markov part as states
(:func:`sinslab.nav.errstate.fix_position_error`), the white part as the fixes' σ and the
velocity error as the white σ of the same long-run variance, ``√(q_v / h)`` for fixes ``h``
apart.

**From the filter's innovations** (:func:`innovation_noise`): a receiver's stated σ can be
optimistic and its errors last, so ``N`` successive fixes carry far less than ``N`` fixes'
information. A filter with the right white R has innovations ``ν = z − H x⁻`` that are
white with covariance ``S = H P⁻ Hᵀ + R`` (Mehra & Peschon 1971); for errors that last,
the R a white-noise filter needs is their *long-run* variance (the spectral density at
zero frequency over the fix interval, ``σ² (1 + 2 Σ_k ρ_k)``: the variance that governs an
average of many fixes). It is measured by batch means (Mohamed & Schwarz's 1999 windowed
innovation covariance, taken over batches instead of single fixes so that a correlation
within a batch counts): per batch ``b`` of ``n_b`` fixes ``n_b ν̄_b²`` has expectation
``mean_b S`` for white innovations and the long-run variance otherwise, so per component::

    σ̂² = mean_b( n_b ν̄_b² − mean_b(H P⁻ Hᵀ) )

with ``H P⁻ Hᵀ = S − R`` of each fix. The filter that follows optimistic fixes absorbs part
of their error, so one pass sees only part of it: the passes are iterated (a
variance-component estimate), each taking ``max(σ used, σ̂)`` as the fixes' σ floor, until
the innovations ask for no more (:func:`sinslab.fusion.recorded.navigate_recorded` with
``FixHandling.fix_noise = "innovations"``). The floor never lowers a σ the file states.

**A velocity bias while it lasts** (:func:`velocity_check`): a σ measured over a whole
drive cannot see a receiver whose velocity is 0.2 m/s off for ten seconds, and a filter
that believes it enters the next outage that far off. Each velocity fix is checked against
the position fixes over the window before it (the position change against the integrated
velocities) and de-weighted by the lasting error they contradict, from earlier fixes only:
the filter cannot know that an outage follows, so the check runs all the time.

With both, a velocity fix the check de-weighted above the common σ is not followed by the
filter, so its innovation shows its whole lasting error; counted in the batch means it
would raise every other fix's σ for an error already de-weighted where it happened. The
batches holding such a fix are left out of that velocity component's estimate
(``governed`` of :func:`innovation_noise`): the floor is measured on the fixes it governs.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import earth as E
from sinslab.core.records import Fixes

__all__ = ["FixErrorModel", "fix_error_model", "given_fix_error", "innovation_noise", "velocity_walk_sigma", "velocity_check",
           "at_rest", "REST_CHI2", "VELOCITY_CHECK_S", "VELOCITY_CHECK_SIGMAS", "VELOCITY_CHECK_WINDOWS",
           "INNOVATION_BATCH_S", "MIN_BATCHES"]


@dataclass(frozen=True)
class FixErrorModel:
    """The fixes' position error: white σ and Gauss–Markov σ, τ per axis (east, north, up)."""

    white: np.ndarray        #: (3,) [m]
    correlated: np.ndarray   #: (3,) steady-state σ of the Gauss–Markov part [m]
    tau: float               #: [s] (one for the three axes)
    lags: np.ndarray         #: (k,) [s] the lags of the structure function
    structure: np.ndarray    #: (k, 3) its measured values [m²]
    velocity_walk: np.ndarray = None  #: (3,) [m/√s] the integrated velocity error's random walk, √q_v
    velocity_tau: float = 0.0         #: [s] the velocity error's correlation time T (0: white)
    rest_fraction: float = 0.0        #: the share of the fixes left out as taken at rest
    #: (3,) [m/s] the velocity error's σ when it is known (a model given by hand), else None
    velocity_sigma: np.ndarray = None

    def velocity_floor(self, h):
        """(3,) [m/s] the white σ of velocity fixes ``h`` [s] apart that carries the
        information of the velocity error (the random walk of its integral, ``√(q_v / h)``,
        and at least its own σ where known), or None when the model has no velocity part."""
        if self.velocity_walk is None:
            return None
        f = self.velocity_walk / math.sqrt(h)
        return f if self.velocity_sigma is None else np.maximum(f, self.velocity_sigma)

    def describe(self):
        s = (f"white {', '.join(f'{x:.2f}' for x in self.white)} m, correlated "
             f"{', '.join(f'{x:.2f}' for x in self.correlated)} m over {self.tau:.0f} s (east, north, up)")
        if self.velocity_sigma is not None:
            s += (f"; velocity error {', '.join(f'{x:.3f}' for x in self.velocity_sigma)} m/s lasting "
                  f"{self.velocity_tau:g} s")
        elif self.velocity_walk is not None:
            s += (f"; velocity walk {', '.join(f'{x:.2f}' for x in self.velocity_walk)} m/√s, the velocity error "
                  f"lasting {self.velocity_tau:.0f} s")
        if self.rest_fraction > 0:
            s += f"; {100 * self.rest_fraction:.0f} % of the fixes at rest left out"
        return s


def given_fix_error(spec) -> FixErrorModel:
    """The :class:`FixErrorModel` of a fix error given by hand (``FixHandling.fix_error``).

    Parameters
    ----------
    spec : FixErrorModel or tuple
        A model (a fit of an earlier record by :func:`fix_error_model`, returned as it is),
        or ``(τ, σ_c, σ_w)``: the position error's Gauss–Markov correlation time [s], its
        steady-state σ and the white σ [m] (each a scalar or east, north, up), or
        ``(τ, σ_c, σ_w, σ_v, T)`` with the velocity fixes' error as a first-order
        Gauss–Markov process of σ ``σ_v`` [m/s] (scalar or east, north, up) and correlation
        time ``T`` [s] (0: white).

    Without the velocity part the velocity fixes keep their stated σ. A receiver's velocity
    error that lasts seconds then holds the filter's velocity, the position follows the
    integral of that error and the fix-error states take the difference: given the true
    position model alone, a filter can end outages farther off than with white fixes. The
    velocity part gives the integrated error's random walk ``q_v = 2σ_v² T`` of the module
    notes (``σ_v² h`` for fixes ``h`` apart when ``T < h/2``: the error is white at the
    fixes), from which the fixes' velocity σ is raised as for a measured model.

    Raises
    ------
    ValueError
        For anything else, or a non-positive τ, a negative or non-finite σ or T.
    """
    if isinstance(spec, FixErrorModel):
        return spec
    if isinstance(spec, (str, bytes)) or not hasattr(spec, "__len__") or len(spec) not in (3, 5):
        raise ValueError("fix_error must be None, 'auto', a FixErrorModel, (tau [s], sigma [m], white [m]) "
                         f"or (tau, sigma, white, velocity sigma [m/s], velocity tau [s]), got {spec!r}")

    def vec(x, what):
        v = np.broadcast_to(np.asarray(x, float), (3,)).copy()
        if not np.all(np.isfinite(v) & (v >= 0)):
            raise ValueError(f"fix_error: {what} must be finite and >= 0, got {x!r}")
        return v

    tau = float(spec[0])
    if not (math.isfinite(tau) and tau > 0):
        raise ValueError(f"fix_error: tau must be > 0 s, got {spec[0]!r}")
    corr, white = vec(spec[1], "sigma"), vec(spec[2], "white sigma")
    walk = sv = None
    tv = 0.0
    if len(spec) == 5:
        sv, tv = vec(spec[3], "velocity sigma"), float(spec[4])
        if not (math.isfinite(tv) and tv >= 0):
            raise ValueError(f"fix_error: velocity tau must be >= 0 s, got {spec[4]!r}")
        walk = sv * math.sqrt(2.0 * tv)
    return FixErrorModel(white, corr, tau, np.zeros(0), np.zeros((0, 3)), walk, tv, velocity_sigma=sv)


def _enu_positions(fixes):
    rm, rn = E.radii(fixes.lat, fixes.h)
    lat0 = float(fixes.lat[0])
    return np.stack([(fixes.lon - fixes.lon[0]) * rn * math.cos(lat0), (fixes.lat - fixes.lat[0]) * rm,
                     fixes.h - fixes.h[0]], -1)


def _integrated_velocity(t, v):
    """The fixes' velocities (J, 3) integrated from the first by the trapezoid rule [m]."""
    return np.vstack([np.zeros((1, 3)), np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t)[:, None], 0)])


#: :func:`at_rest`: a fix is at rest when the χ² of its horizontal speed against its stated
#: velocity σ (two degrees of freedom) is below its 99 % quantile, ``−2 ln 0.01`` (a speed
#: that cannot be told from zero)
REST_CHI2 = -2.0 * math.log(0.01)


def at_rest(vel, sigma_vel):
    """(J,) bool: the fixes whose horizontal velocity cannot be told from zero,
    ``(v_E/σ_E)² + (v_N/σ_N)² < REST_CHI2`` (:data:`REST_CHI2`); a fix without a positive
    σ is not at rest.

    Parameters
    ----------
    vel : array (J, 3)
        The fixes' velocities, east, north, up [m/s].
    sigma_vel : array (J, 3) or (3,)
        Their stated σ [m/s].
    """
    v = np.asarray(vel, float)[:, :2]
    s = np.broadcast_to(np.asarray(sigma_vel, float), np.shape(vel))[:, :2]
    good = np.all(np.isfinite(s) & (s > 0), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        chi2 = np.sum((v / np.where(s > 0, s, 1.0)) ** 2, axis=1)
    return good & (chi2 < REST_CHI2)


def fix_error_model(fixes: Fixes, *, max_lag=120.0, n_lags=24, gap=None):
    """The :class:`FixErrorModel` of ``fixes`` (see the module notes), or None when they
    have no velocities or, without the fixes at rest, span less than four lags. Gaps longer
    than ``gap`` [s] (default 3 fix intervals) break the integration: pairs across them are
    not used. A stop is not a gap: the moving stretches either side of it are joined."""
    got = _structure(fixes, max_lag, n_lags, gap, stops=False)
    if got is None:
        return None
    D, lags, h, rest = got
    return dataclasses.replace(_fit(D, lags, h), rest_fraction=float(np.mean(rest)))


def _structure(fixes, max_lag, n_lags, gap, *, stops):
    """``(D (k, 3) [m²], lags (k,) [s], h [s], rest (J,) bool)``: the structure function of
    the module notes, the fixes at rest left out (``stops`` False) or counted, or None."""
    if fixes.vel is None or len(fixes) < 20:
        return None
    t = fixes.t
    h = float(np.median(np.diff(t)))
    gap = 3.0 * h if gap is None else float(gap)
    p = _enu_positions(fixes)
    seg = np.concatenate([[0], np.cumsum(np.diff(t) > gap)])       # integration segments
    iv = _integrated_velocity(t, fixes.vel)
    rest = np.zeros(len(fixes), bool)
    if not stops and fixes.sigma_vel is not None:
        rest = at_rest(fixes.vel, fixes.sigma_vel)
        p, iv, seg = p[~rest], iv[~rest], seg[~rest]
        if p.shape[0] < 20:
            return None
    span = float(t[-1] - t[0]) - h * int(rest.sum())
    max_lag = min(max_lag, span / 4)
    if max_lag < 4 * h:
        return None
    lags = np.unique(np.round(np.geomspace(h, max_lag, n_lags) / h).astype(int))
    D, used = [], []
    for m in lags:
        ok = seg[m:] == seg[:-m]
        if ok.sum() < 10:
            continue
        d = (p[m:] - p[:-m]) - (iv[m:] - iv[:-m])
        D.append(np.mean(d[ok] ** 2, 0))
        used.append(m * h)
    if len(used) < 4:
        return None
    return np.array(D), np.array(used), h, rest


def _fit(D, lags, h, *, velocity_correlation=True):
    """The model of the module notes fitted to the structure function ``D`` (k, 3) [m²]
    at ``lags`` (k,) [s]: non-negative least squares in relative residuals for each
    (τ, T) of the grids, the pair of the smallest residual summed over the axes kept
    (``velocity_correlation`` False: T = 0 only, the velocity error white)."""
    from scipy.optimize import nnls
    top = 0.5 * float(lags[-1])
    taus = np.geomspace(max(2 * h, 0.5), top, 40)
    tvs = np.array([0.0])                                                   # 0: the random-walk limit
    if velocity_correlation:
        tvs = np.concatenate([tvs, np.geomspace(max(h, 0.5), top, 20)])
    best = None
    for tau in taus:
        gm = 2.0 * (1.0 - np.exp(-lags / tau))
        for tv in tvs:
            walk = lags if tv == 0.0 else lags - tv * (1.0 - np.exp(-lags / tv))
            A = np.column_stack([np.full(lags.size, 2.0), gm, walk])
            cost, coef = 0.0, []
            for k in range(3):
                w = 1.0 / np.maximum(D[:, k], 1e-8)
                c, r = nnls(A * w[:, None], D[:, k] * w)
                cost += r * r
                coef.append(c)
            if best is None or cost < best[0]:
                best = (cost, tau, tv, np.array(coef))
    _, tau, tv, coef = best
    return FixErrorModel(np.sqrt(coef[:, 0]), np.sqrt(coef[:, 1]), float(tau), lags, D,
                         np.sqrt(coef[:, 2]), float(tv))


#: batch length of :func:`innovation_noise` [s]: longer than a Doppler velocity error lasts
#: (seconds), short enough for many batches in a drive
INNOVATION_BATCH_S = 10.0
#: fewest whole batches :func:`innovation_noise` estimates from
MIN_BATCHES = 10


def innovation_noise(t, innovation, innovation_sigma, sigma, *, batch=INNOVATION_BATCH_S,
                     min_batches=MIN_BATCHES, governed=None):
    """The fixes' white σ that matches the long-run variance of the filter's innovations
    (see the module notes).

    Parameters
    ----------
    t : array (J,)
        Validity times of the applied fixes [s], increasing.
    innovation, innovation_sigma : arrays (J, m)
        Innovations ``ν`` and the filter's σ of each (``√S_ii``).
    sigma : array (J, m)
        The σ each fix was applied with (``√R_ii``).
    batch : float
        Batch length [s]; only batches holding at least 80 % of the fixes a whole batch
        holds are used (none straddles an outage or a gap).
    min_batches : int
    governed : bool array (J, m), optional
        Where the σ this estimate sets governs the fix (default: everywhere). A fix whose
        σ something else set (a velocity fix the :func:`velocity_check` de-weighted) is not
        followed by the filter, so its innovation shows its whole lasting error: counted,
        it would raise every other fix's σ for an error already de-weighted where it
        happened. A component's batches holding such a fix are left out of its estimate
        (all its batches are used when fewer than ``min_batches`` would remain).

    Returns
    -------
    (σ̂ (m,), batches) or None
        ``σ̂`` per component (0 where the innovations are smaller than the filter's own
        uncertainty explains), and the number of batches; None with fewer than
        ``min_batches``.
    """
    t = np.asarray(t, float)
    nu = np.asarray(innovation, float).reshape(t.size, -1)
    hph = np.asarray(innovation_sigma, float).reshape(nu.shape) ** 2 - np.asarray(sigma, float).reshape(nu.shape) ** 2
    if t.size < 2:
        return None
    h = float(np.median(np.diff(t)))
    b = np.floor((t - t[0]) / batch).astype(np.int64)
    n = np.bincount(b).astype(float)
    full = n >= 0.8 * batch / h
    if int(full.sum()) < min_batches:
        return None
    cols = range(nu.shape[1])
    s_nu = np.stack([np.bincount(b, nu[:, i]) for i in cols], -1)[full]
    s_hph = np.stack([np.bincount(b, hph[:, i]) for i in cols], -1)[full]
    nf = n[full, None]
    stat = s_nu ** 2 / nf - s_hph / nf
    if governed is None:
        est = np.mean(stat, axis=0)
    else:
        off = np.asarray(governed, bool).reshape(nu.shape) == 0
        clean = np.stack([np.bincount(b, off[:, i], minlength=n.size) for i in cols], -1)[full] == 0
        enough = clean.sum(0) >= min_batches
        keep = np.where(enough, clean, True)
        est = np.sum(stat * keep, 0) / np.sum(keep, 0)
    return np.sqrt(np.maximum(est, 0.0)), int(full.sum())


def velocity_walk_sigma(fixes: Fixes):
    """The velocity σ floor of ``fix_noise = "innovations"``: per velocity component (east,
    north, up [m/s]) the white σ that carries the information of the random walk ``q_v`` of
    the fixes' integrated velocity against their positions (``q_v / h`` for fixes ``h``
    apart), or None (no velocities, too short a record).

    That filter carries no fix-error states and one floor for every velocity fix, at rest
    too: ``q_v`` is fitted over the whole record with its stops counted, the velocity error
    taken white (``T = 0``), so the walk stands for every lasting error of the fixes a
    filter without position states can absorb through its velocity. (:func:`fix_error_model`
    separates the velocity error's own correlation and the position's Gauss–Markov part,
    which only a filter carrying those states can use.)"""
    got = _structure(fixes, 120.0, 24, None, stops=True)
    if got is None:
        return None
    D, lags, h, _ = got
    return _fit(D, lags, h, velocity_correlation=False).velocity_floor(h)


#: trailing window of :func:`velocity_check` [s]: as long as the receiver's velocity errors
#: last (the 10 s batches of :func:`innovation_noise`); shorter windows let a receiver that
#: moves its positions with its biased velocity hide the bias
VELOCITY_CHECK_S = 10.0
#: :func:`velocity_check` raises a σ only where the window's mean error passes this many of
#: the check's own robust scatter (a 3σ detector: the position fixes' noise alone rarely does)
VELOCITY_CHECK_SIGMAS = 3.0
#: :func:`velocity_check` raises no σ before it has seen this many windows' worth of checks
VELOCITY_CHECK_WINDOWS = 3


def velocity_check(fixes: Fixes, window=VELOCITY_CHECK_S, *, sigmas=VELOCITY_CHECK_SIGMAS, gap=None):
    """Each velocity fix checked against the position fixes over the ``window`` [s] before it.

    Over the window ``[t_j, t_k]`` the position change minus the integrated velocities
    (trapezoid rule) is the change of the position error minus the window's velocity error
    integrated, so ``d_k = ((p_k − p_j) − ∫ v dt) / (t_k − t_j)`` is the window's mean
    velocity error the positions contradict (east, north, up [m/s]), plus the position
    fixes' own error change over the window. That second part sets the check's scatter
    where nothing lasts: per axis ``s_k = 1.4826 median |d|`` over the checks up to fix ``k``
    (a robust σ: a short biased stretch moves it little; none before
    :data:`VELOCITY_CHECK_WINDOWS` windows' worth of checks). An error that lasts the window is not averaged by
    the ``n_k = k − j`` fixes in it: a white σ carrying the same information is
    ``√n_k |d_k|`` (one batch's long-run variance, as the batch means of
    :func:`innovation_noise`, from the fixes alone). With the scatter a detector may
    not count (``sigmas`` of it) taken off, each fix's velocity σ becomes::

        σ_k² = σ_stated² + n_k max(0, d_k² − (sigmas · s_k)²)

    per axis: a velocity bias that lasts is de-weighted while it lasts, from fixes up to
    ``t_k`` only (the filter cannot know an outage follows); elsewhere the σ stay as stated.
    Fixes without a whole window behind them (the first ``window``, after a gap longer than
    ``gap``, default three fix intervals) keep their σ, and so does the vertical of 2-D
    fixes (no height).

    Returns
    -------
    (σ (J, 3) [m/s], d (J, 3) [m/s], s (3,) [m/s] at the last fix, NaN if never reached) or
    None (no velocities, fewer than three fixes)
    """
    if fixes.vel is None or len(fixes) < 3:
        return None
    t = np.asarray(fixes.t, float)
    h = float(np.median(np.diff(t)))
    gap = 3.0 * h if gap is None else float(gap)
    p = _enu_positions(fixes)
    iv = _integrated_velocity(t, np.asarray(fixes.vel, float))
    j = np.searchsorted(t, t - float(window) + 1e-9)              # the first fix of each window
    seg = np.concatenate([[0], np.cumsum(np.diff(t) > gap)])
    ok = (seg[j] == seg) & (t - t[j] >= 0.8 * float(window))
    d = np.zeros_like(p)
    d[ok] = ((p[ok] - p[j[ok]]) - (iv[ok] - iv[j[ok]])) / (t[ok] - t[j[ok]])[:, None]
    d = np.nan_to_num(d, nan=0.0)                                 # 2-D fixes: no height to check against
    scatter = _running_scatter(d, ok, VELOCITY_CHECK_WINDOWS * max(int(round(float(window) / h)), 1))
    n = np.where(ok, np.arange(t.size) - j, 0).astype(float)[:, None]
    base = np.broadcast_to(np.asarray(0.0 if fixes.sigma_vel is None else fixes.sigma_vel, float), d.shape)
    excess = np.maximum(d ** 2 - (float(sigmas) * scatter) ** 2, 0.0)     # 0 where no scatter yet (inf)
    last = scatter[-1] if np.all(np.isfinite(scatter[-1])) else np.full(3, np.nan)
    return np.sqrt(base ** 2 + n * excess), d, last



def _running_scatter(d, ok, min_count):
    """Per fix and axis the robust σ (``1.4826 median |d|``) of the checks ``d`` (J, 3) of
    the fixes up to it where ``ok``; inf before ``min_count`` of them."""
    import bisect
    out = np.full(d.shape, np.inf)
    seen = [[], [], []]
    for k in range(d.shape[0]):
        if ok[k]:
            for i in range(3):
                bisect.insort(seen[i], abs(float(d[k, i])))
        m = len(seen[0])
        if m >= min_count:
            out[k] = [1.4826 * seen[i][m // 2] for i in range(3)]
    return out
