"""Oscillation components of navigation error series: Schuler, Foucault, 24 h.

The errors of an undamped INS are, to first order, a sum of a few known oscillations
(static-base error model; Qin, *Inertial Navigation*, 2006, §7): the Schuler oscillation
at ω_s = sqrt(g/R) (period ≈ 84.4 min), modulated by the Foucault rotation ω_f = ω_ie sin L
— which splits the Schuler line into the two lines ω_s ± ω_f — and the Earth-period
oscillation at ω_ie (24 h, sidereal), on top of a bias and a slow trend (position errors
drift). This module turns "the Schuler oscillation is reduced by half" into numbers.

:func:`fit_components` — linear least squares on the known frequencies::

    x(t) = b0 + b1·τ [+ b2·τ²] + Σ_k (a_k cos ω_k t + c_k sin ω_k t) + residual,  τ = t/T

with ``ω_k ∈ {ω_s, ω_s − ω_f, ω_s + ω_f, ω_ie}``. Line amplitudes are ``sqrt(a_k² + c_k²)``.
Summary amplitudes (the numbers the experiments compare):

- ``schuler``: the *equivalent amplitude* of the Schuler band (the ω_s line plus the
  two Foucault side lines), ``√2 · RMS`` over the record of the fitted band signal. For a
  pure sinusoid it is its amplitude; for a Foucault-modulated ``A cos(ω_f t) sin(ω_s t)``
  observed over whole Foucault periods it is ``A/√2``; it stays meaningful when the lines
  are not fully resolved (it is the RMS of their sum, not a sum of separate amplitudes).
- ``foucault``: the same for the two side lines only;
- ``earth``: amplitude of the ω_ie line.

The side lines are fitted only when the record resolves them from the centre line
(``foucault="auto"``: ``ω_f·T ≥ π``, about 17 h at 45°); otherwise the single ω_s line
absorbs the slow modulation. The 24 h line over a record much shorter than a day is
nearly collinear with bias and trend: ``earth="auto"`` fits it when ``ω_ie·T ≥ π/2``
(6 h) and the result says so in ``notes``.

:func:`amplitude_spectrum` — a Hann-windowed, zero-padded periodogram scaled so that a
sinusoid of amplitude A shows a peak of height A (uniform sampling), or the Lomb–Scargle
periodogram (any sampling, e.g. recorded data with gaps) with the same scaling.
:func:`band_peak` reads the largest line in a frequency band.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sinslab.core import earth

__all__ = ["Components", "fit_components", "known_frequencies", "amplitude_spectrum",
           "band_peak", "resample_uniform"]


def known_frequencies(lat, h=0.0, omega_s=None):
    """``{"schuler": ω_s, "schuler_minus": ω_s − |ω_f|, "schuler_plus": ω_s + |ω_f|,
    "earth": ω_ie}`` [rad/s] at latitude ``lat`` [rad] and height ``h`` [m]."""
    ws = float(earth.schuler_frequency(lat, h)) if omega_s is None else float(omega_s)
    wf = abs(float(earth.foucault_frequency(lat)))
    return {"schuler": ws, "schuler_minus": ws - wf, "schuler_plus": ws + wf,
            "earth": earth.WIE}


@dataclass(frozen=True)
class Components:
    """Result of :func:`fit_components` (amplitudes in the unit of the input series).

    Attributes
    ----------
    schuler : float
        Equivalent amplitude of the Schuler band (ω_s and, when fitted, ω_s ± ω_f):
        √2 × RMS over the record of the fitted band signal.
    foucault : float
        Equivalent amplitude of the side lines ω_s ± ω_f (NaN when not fitted).
    earth : float
        Amplitude of the ω_ie (24 h) line (NaN when not fitted).
    lines : dict
        ``{name: (omega [rad/s], amplitude, phase [rad])}`` of every fitted line, with
        ``x ∋ amplitude·cos(ω t − phase)`` (t from the first sample).
    bias, trend : float
        Constant and the change of the linear term over the record.
    residual_rms : float
        RMS of what the model does not explain.
    duration : float
        Record length [s].
    foucault_fitted, earth_fitted : bool
    notes : tuple of str
    """

    schuler: float
    foucault: float
    earth: float
    lines: dict
    bias: float
    trend: float
    residual_rms: float
    duration: float
    foucault_fitted: bool
    earth_fitted: bool
    notes: tuple = ()
    _fit: dict = field(default=None, repr=False, compare=False)

    def band(self, which="schuler"):
        """Fitted signal of a band (``"schuler"``, ``"foucault"``, ``"earth"``, ``"slow"``
        = bias + trend + earth, ``"all"``) at the input epochs."""
        f = self._fit
        cols = f["groups"][which]
        return f["A"][:, cols] @ f["coef"][cols]


def _clean(t, x):
    t = np.asarray(t, dtype=float).reshape(-1)
    x = np.asarray(x, dtype=float).reshape(-1)
    if t.shape != x.shape:
        raise ValueError(f"t and x must have the same length, got {t.size} and {x.size}")
    ok = np.isfinite(t) & np.isfinite(x)
    if ok.sum() < 8:
        raise ValueError("need at least 8 finite samples")
    t, x = t[ok], x[ok]
    if np.any(np.diff(t) <= 0):
        raise ValueError("t must be strictly increasing")
    return t, x


def fit_components(t, x, *, lat, h=0.0, omega_s=None, foucault="auto", earth="auto",
                   quadratic=False) -> Components:
    """Least-squares amplitudes of the Schuler, Foucault side-line and 24 h components.

    Parameters
    ----------
    t : array_like (M,)
        Epochs [s], strictly increasing (any spacing; NaN samples are dropped).
    x : array_like (M,)
        The error series (any unit: the amplitudes come out in it).
    lat, h : float
        Latitude [rad] and height [m] for ω_s and ω_f (mean of a voyage).
    omega_s : float, optional
        Schuler frequency [rad/s] to use instead of the local one.
    foucault, earth : "auto" | bool
        Whether to fit the ω_s ± ω_f side lines and the ω_ie line (see module notes).
    quadratic : bool
        Also fit a quadratic trend (slowly diverging errors).

    Returns
    -------
    Components
    """
    t, x = _clean(t, x)
    t0 = t[0]
    tt = t - t0
    T = float(tt[-1])
    if T <= 0:
        raise ValueError("record has zero length")
    w = known_frequencies(lat, h, omega_s)
    wf = w["schuler_plus"] - w["schuler"]
    notes = []
    if foucault == "auto":
        foucault = wf * T >= math.pi
        if not foucault:
            notes.append(f"Foucault side lines not fitted: the record ({T / 3600:.3g} h) does not "
                         f"resolve them (needs {math.pi / max(wf, 1e-30) / 3600:.3g} h)")
    if earth == "auto":
        earth = w["earth"] * T >= math.pi / 2
        if not earth:
            notes.append(f"24 h line not fitted: record ({T / 3600:.3g} h) shorter than 6 h")
    elif earth and w["earth"] * T < math.pi:
        notes.append(f"24 h line fitted on a {T / 3600:.3g} h record: nearly collinear with "
                     "bias and trend, its amplitude is poorly determined")
    if w["schuler"] * T < math.pi:
        notes.append("record shorter than half a Schuler period: Schuler amplitude unreliable")
    tau = tt / T
    cols = [np.ones_like(tt), tau]
    names = ["bias", "trend"]
    if quadratic:
        cols.append(tau * tau)
        names.append("quad")
    lines = ["schuler"] + (["schuler_minus", "schuler_plus"] if foucault else []) + \
        (["earth"] if earth else [])
    for ln in lines:
        cols += [np.cos(w[ln] * tt), np.sin(w[ln] * tt)]
        names += [ln + "_c", ln + "_s"]
    A = np.column_stack(cols)
    scale = np.sqrt((A * A).mean(0))
    coef, *_ = np.linalg.lstsq(A / scale, x, rcond=None)
    coef = coef / scale
    resid = x - A @ coef
    idx = {n: i for i, n in enumerate(names)}
    out_lines = {}
    for ln in lines:
        a, c = coef[idx[ln + "_c"]], coef[idx[ln + "_s"]]
        out_lines[ln] = (w[ln], float(math.hypot(a, c)), float(math.atan2(c, a)))

    def grp(*lns):
        return [idx[ln + s] for ln in lns if ln in lines for s in ("_c", "_s")]

    groups = {"schuler": grp("schuler", "schuler_minus", "schuler_plus"),
              "foucault": grp("schuler_minus", "schuler_plus"),
              "earth": grp("earth"),
              "slow": [idx[n] for n in names if n in ("bias", "trend", "quad")] + grp("earth"),
              "all": list(range(len(names)))}

    def eq_amp(g):
        if not g:
            return float("nan")
        s = A[:, g] @ coef[g]
        return float(math.sqrt(2.0 * np.mean(s * s)))

    return Components(
        schuler=eq_amp(groups["schuler"]),
        foucault=eq_amp(groups["foucault"]),
        earth=out_lines["earth"][1] if earth else float("nan"),
        lines=out_lines, bias=float(coef[0]), trend=float(coef[1]),
        residual_rms=float(math.sqrt(np.mean(resid * resid))), duration=T,
        foucault_fitted=bool(foucault), earth_fitted=bool(earth), notes=tuple(notes),
        _fit={"A": A, "coef": coef, "groups": groups})


def resample_uniform(t, x, dt):
    """Linear interpolation of (t, x) onto a uniform grid of step ``dt`` [s]."""
    t, x = _clean(t, x)
    tg = np.arange(t[0], t[-1] + 0.5 * dt, dt)
    return tg, np.interp(tg, t, x)


def amplitude_spectrum(t, x, *, method="periodogram", detrend="linear", pad=8,
                       fmax=None, freqs=None):
    """Amplitude spectrum of an error series: a sinusoid of amplitude A peaks at ≈ A.

    Parameters
    ----------
    t, x : array_like (M,)
        Epochs [s] and values.
    method : {"periodogram", "lombscargle"}
        ``"periodogram"``: Hann window, zero padding ×``pad`` (uniform sampling
        required; the peak of a sinusoid between bins is recovered to < 1 %).
        ``"lombscargle"``: scipy's Lomb–Scargle on the given epochs (gaps allowed),
        scaled to amplitude (``2·sqrt(P/M)``).
    detrend : {"linear", "constant", None}
    pad : int
        Zero-padding factor of the periodogram.
    fmax : float, optional
        Highest frequency kept [Hz].
    freqs : array_like, optional
        Frequencies [Hz] for Lomb–Scargle (default: 0 < f ≤ fmax on a grid 1/(pad·T)).

    Returns
    -------
    f : ndarray
        Frequencies [Hz].
    amp : ndarray
        Amplitude (unit of ``x``).
    """
    t, x = _clean(t, x)
    T = t[-1] - t[0]
    if detrend == "linear":
        p = np.polyfit(t - t[0], x, 1)
        x = x - np.polyval(p, t - t[0])
    elif detrend == "constant":
        x = x - x.mean()
    elif detrend is not None:
        raise ValueError(f"detrend must be 'linear', 'constant' or None, got {detrend!r}")
    if method == "periodogram":
        d = np.diff(t)
        dt = float(np.mean(d))
        if np.max(np.abs(d - dt)) > 1e-3 * dt:
            raise ValueError("the periodogram needs uniform sampling: use method='lombscargle' "
                             "or resample_uniform()")
        M = x.size
        win = np.hanning(M)
        nfft = int(2 ** math.ceil(math.log2(max(M * int(pad), 2))))
        X = np.fft.rfft(x * win, nfft)
        f = np.fft.rfftfreq(nfft, dt)
        amp = 2.0 * np.abs(X) / win.sum()
    elif method == "lombscargle":
        from scipy.signal import lombscargle

        M = x.size
        if freqs is None:
            dtm = T / (M - 1)
            top = 0.5 / dtm if fmax is None else float(fmax)
            df = 1.0 / (int(pad) * T)
            f = np.arange(df, top + 0.5 * df, df)
        else:
            f = np.asarray(freqs, dtype=float)
            if np.any(f <= 0):
                raise ValueError("Lomb–Scargle frequencies must be > 0")
        P = lombscargle(t - t[0], x, 2 * np.pi * f)
        amp = 2.0 * np.sqrt(P / M)
    else:
        raise ValueError(f"method must be 'periodogram' or 'lombscargle', got {method!r}")
    if fmax is not None:
        keep = f <= fmax
        f, amp = f[keep], amp[keep]
    return f, amp


def band_peak(f, amp, f_lo, f_hi):
    """``(frequency, amplitude)`` of the largest spectrum value in ``[f_lo, f_hi]`` [Hz]."""
    f = np.asarray(f)
    amp = np.asarray(amp)
    m = (f >= f_lo) & (f <= f_hi)
    if not m.any():
        raise ValueError(f"no spectrum bins in [{f_lo:g}, {f_hi:g}] Hz")
    i = int(np.argmax(np.where(m, amp, -np.inf)))
    return float(f[i]), float(amp[i])
