"""Raw GNSS reading (sinslab.data.gnss) on the rtklib-walk u-blox log: what the log holds,
Doppler against the pseudorange rate (sign and units), the RINEX path as a round trip
through RTKLIB's own converter, the receiver's NAV-PVT against the RTK reference, and the
one-line errors of bad files."""
import math
from pathlib import Path

import numpy as np
import pytest

from sinslab.core.errors import InputError

WALK = Path(__file__).resolve().parents[3] / "shared" / "data" / "rtklib-walk"
UBX = WALK / "gnss_1730.ubx"
needs_walk = pytest.mark.skipif(not UBX.exists(), reason="rtklib-walk not available")


@pytest.fixture(scope="module")
def walk():
    from sinslab.data.gnss import read_gnss_raw
    return read_gnss_raw(UBX)


@needs_walk
def test_walk_log_contents(walk):
    g = walk
    assert g.epoch_t.size == 536 and np.allclose(np.diff(g.epoch_t), 0.25, atol=1e-6)
    assert g.systems == ["C", "E", "G", "S"]
    assert {s[0] for s in g.eph.sat} == {"G", "E", "C"} and len(g.eph) >= 20
    # C/N0 in dB-Hz (a unit slip of 1000 once made every satellite look 45 dB weak)
    assert 15 < np.percentile(g.cn0, 1) and np.percentile(g.cn0, 99) < 60
    # t_ref is a GPS week start: the times of day of the log are 17:30..17:33 GPST
    tod = np.mod(g.t_abs, 86400.0)
    assert 17.5 * 3600 < tod[0] < tod[-1] < 17.6 * 3600


@needs_walk
def test_doppler_is_minus_the_pseudorange_rate(walk):
    """−λ D equals the pseudorange rate (differences over 0.25 s), per satellite: the
    range rate plus the clock drift, both in it (median over the log, 0.2 m/s)."""
    from sinslab.core.gnss import C_LIGHT
    g = walk
    for s in ("G10", "E07", "C21"):
        m = (g.sat == s) & np.isfinite(g.doppler)
        e, P, D, f = g.epoch[m], g.pseudorange[m], g.doppler[m], g.freq[m]
        ok = np.diff(e) == 1
        rate = np.diff(P)[ok] / 0.25
        dop = (-(C_LIGHT / f) * D)[:-1][ok]
        assert abs(np.median(rate - 0.5 * (dop + (-(C_LIGHT / f) * D)[1:][ok]))) < 0.2, s


@needs_walk
def test_phase_rate_is_minus_the_doppler(walk):
    """Carrier phase of every slot: its rate over 0.25 s is minus the Doppler (RINEX sign)
    to 0.2 Hz in the median (the Doppler is ~±3 kHz: a wrong sign
    would miss by twice it), code minus carrier changes by centimetres between epochs
    without a slip flag (ionosphere divergence is mm/s), and 85–95 % of the pseudoranges
    have a phase beside them."""
    from sinslab.core.gnss import C_LIGHT
    g = walk
    S = g.signals
    share = np.isfinite(S.phase).sum() / np.isfinite(S.pseudorange).sum()
    assert 0.85 < share < 0.95
    assert set(S.code[:, 1][S.code[:, 1] != ""]) == {"2X"} and "5X" in set(S.code[:, 2])
    for s in ("G10", "E07", "C21"):
        m = g.sat == s
        for j in range(3):
            L, D, f = S.phase[m, j], S.doppler[m, j], S.freq[m, j]
            ok = (np.diff(g.epoch[m]) == 1) & np.isfinite(np.diff(L)) & ~S.slip[m, j][1:]
            if ok.sum() < 50:
                continue
            assert abs(np.median((np.diff(L) / 0.25 + 0.5 * (D[1:] + D[:-1]))[ok])) < 0.2, (s, j)
            cmc = S.pseudorange[m, j] - L * C_LIGHT / f
            assert np.median(np.abs(np.diff(cmc)[ok])) < 0.1, (s, j)


def test_static_pair_signals():
    """The static pair's RINEX 3.04 files: rover and base carry the same carriers with
    other tracking codes (rover L2W/E5bQ/E5aQ, base L2W/E7X/E5X), every slot with phase;
    the rover flags no loss of lock, the base flags every signal at 12:00:18 (its
    geometry-free combination continuous there: a receiver event, not slips) and G02 at
    12:00:39–40, where its code and phase jump by tens of metres and back."""
    from sinslab.data.gnss import read_gnss_raw
    d = Path(__file__).resolve().parents[3] / "shared" / "data" / "cssrlib-static-rtk"
    if not d.exists():
        pytest.skip("cssrlib-static-rtk not available")
    rov = read_gnss_raw(d / "SEPT078M1.21O", d / "SEPT078M.21P")
    base = read_gnss_raw(d / "3034078M1.21O", d / "SEPT078M.21P")
    assert rov.epoch_t.size == base.epoch_t.size == 60 and np.allclose(rov.epoch_t, base.epoch_t)
    gal = rov.sat.astype("U1") == "E"
    assert set(map(tuple, rov.signals.code[gal])) == {("1C", "7Q", "5Q")}
    assert set(map(tuple, base.signals.code[base.sat.astype("U1") == "E"])) == {("1X", "7X", "5X")}
    has = rov.signals.code != ""
    assert np.sum(~np.isfinite(rov.signals.phase[has])) == 2
    assert not rov.signals.slip.any()
    flagged = {(int(e), s) for e, s in zip(base.epoch[base.signals.slip.any(1)], base.sat[base.signals.slip.any(1)])}
    assert flagged == {(18, s) for s in base.sat[base.epoch == 18]} | {(39, "G02"), (40, "G02")}


@needs_walk
def test_rinex_round_trip(tmp_path, walk):
    """The log converted to RINEX 3.04 observations + navigation by RTKLIB's convrnx and
    read back: the same epochs, pseudoranges to the file's 1 mm, phases to its 1e-3 cycles with
    their slip flags, the same satellite
    positions from the navigation file's ephemerides."""
    rtk = pytest.importorskip("pyrtklib5")
    from sinslab.core.gnss import transmit_states
    from sinslab.data.gnss import read_gnss_raw
    opt = rtk.rnxopt_t()
    opt.rnxver = 304
    opt.navsys = rtk.SYS_GPS | rtk.SYS_GAL | rtk.SYS_CMP
    opt.obstype = 1 | 2 | 4 | 8           # pseudorange, phase, Doppler, C/N0
    opt.freqtype = 1 | 2 | 4
    opt.ttol = 0.005
    obs, nav = tmp_path / "w.obs", tmp_path / "w.nav"
    assert rtk.convrnx(rtk.STRFMT_UBX, opt, str(UBX), [str(obs), str(nav)] + [""] * 7) == 1
    r = read_gnss_raw(obs, nav)
    g = walk
    assert np.allclose(r.epoch_t, g.epoch_t, atol=1e-6)
    keys_g = {(e, s): p for e, s, p in zip(g.epoch, g.sat, g.pseudorange) if s[0] in "GEC"}
    keys_r = {(e, s): p for e, s, p in zip(r.epoch, r.sat, r.pseudorange)}
    common = set(keys_g) & set(keys_r)
    assert len(common) > 0.9 * len(keys_g)
    assert max(abs(keys_g[k] - keys_r[k]) for k in common) < 1e-3
    # carrier phase of every slot: the file's 1e-3 cycles, and the slip flags kept
    ph_g = {(e, s, j): (p, f) for e, s, row, fl in zip(g.epoch, g.sat, g.signals.phase, g.signals.slip)
            if s[0] in "GEC" for j, (p, f) in enumerate(zip(row, fl)) if np.isfinite(p)}
    ph_r = {(e, s, j): (p, f) for e, s, row, fl in zip(r.epoch, r.sat, r.signals.phase, r.signals.slip)
            for j, (p, f) in enumerate(zip(row, fl)) if np.isfinite(p)}
    both = set(ph_g) & set(ph_r)
    assert len(both) > 0.9 * len(ph_g)
    assert max(abs(ph_g[k][0] - ph_r[k][0]) for k in both) < 2e-3
    assert sum(ph_g[k][1] for k in both) == sum(ph_r[k][1] for k in both) > 0
    m = g.sat == "G10"
    pg = transmit_states(g.eph, None, g.sat[m][-1:], g.epoch_t[g.epoch[m][-1:]], g.pseudorange[m][-1:])[0]
    mr = r.sat == "G10"
    pr = transmit_states(r.eph, None, r.sat[mr][-1:], r.epoch_t[r.epoch[mr][-1:]], r.pseudorange[mr][-1:])[0]
    assert np.max(np.abs(pg - pr)) < 0.01


@needs_walk
def test_nav_pvt_is_the_receivers_rtk(walk):
    """The receiver's NAV-PVT fixes coincide horizontally with the RTK reference (the
    receiver ran RTK itself); 536 of them at the RAWX epochs."""
    from sinslab.core import earth as E
    from sinslab.data import read_fixes
    pvt = read_fixes(UBX)
    ref = read_fixes(WALK / "gnss_1730_sf.pos")
    assert len(pvt) == 536
    j = np.searchsorted(ref.t, pvt.t - 0.01)
    ok = (j < len(ref)) & (np.abs(ref.t[np.minimum(j, len(ref) - 1)] - pvt.t) < 0.01)
    rm, rn = E.radii(ref.lat[0], ref.h[0])
    dn = (pvt.lat[ok] - ref.lat[j[ok]]) * rm
    de = (pvt.lon[ok] - ref.lon[j[ok]]) * rn * math.cos(ref.lat[0])
    assert ok.sum() > 500 and np.max(np.hypot(dn, de)) < 0.02


def test_bad_files(tmp_path):
    from sinslab.data.gnss import read_gnss_raw
    empty = tmp_path / "empty.ubx"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="empty.ubx: empty file"):
        read_gnss_raw(empty)
    junk = tmp_path / "junk.ubx"
    junk.write_bytes(bytes(range(256)) * 40)
    with pytest.raises(InputError, match="junk.ubx: no raw measurements"):
        read_gnss_raw(junk)
    r4 = tmp_path / "v4.obs"
    r4.write_text("     4.01           OBSERVATION DATA    M                   RINEX VERSION / TYPE\n")
    with pytest.raises(InputError, match="v4.obs: RINEX version 4.01"):
        read_gnss_raw(r4)
    with pytest.raises(InputError, match="nothere.ubx: no such file"):
        read_gnss_raw(tmp_path / "nothere.ubx")


@needs_walk
def test_log_without_raw_measurements(tmp_path):
    """A u-blox log with NAV-PVT only (the raw messages filtered out by pyubx2)."""
    from pyubx2 import UBXReader
    from sinslab.data.gnss import read_gnss_raw
    out = tmp_path / "pvt_only.ubx"
    with open(UBX, "rb") as fh, open(out, "wb") as w:
        for raw, msg in UBXReader(fh, protfilter=2, quitonerror=0):
            if msg is not None and msg.identity == "NAV-PVT":
                w.write(raw)
    with pytest.raises(InputError, match="pvt_only.ubx: no raw measurements"):
        read_gnss_raw(out)


STATIC = Path(__file__).resolve().parents[3] / "shared" / "data" / "cssrlib-static-rtk"
needs_static = pytest.mark.skipif(not (STATIC / "SEPT078M1.21O").exists(), reason="cssrlib-static-rtk not available")


@needs_static
def test_rinex_faults_name_their_real_cause(tmp_path):
    """A header without END OF HEADER (it read as 'without records'), a navigation file of
    another day (the error named the observation file: 'no satellite has an ephemeris') and
    a folder given as the log (IsADirectoryError)."""
    from sinslab.data.gnss import read_gnss_raw

    obs, nav = STATIC / "SEPT078M1.21O", STATIC / "SEPT078M.21P"
    text = obs.read_text()
    cut = tmp_path / "noend.21O"
    cut.write_text("".join(ln for ln in text.splitlines(True) if "END OF HEADER" not in ln))
    with pytest.raises(InputError, match=r"noend.21O: the RINEX header has no END OF HEADER line"):
        read_gnss_raw(cut, nav)
    later = tmp_path / "later.21O"
    later.write_text("".join(ln.replace("> 2021 03 19", "> 2021 03 26", 1) for ln in text.splitlines(True)))
    with pytest.raises(InputError, match=r"SEPT078M.21P: its ephemerides are for 2021-03-19 .* the observations of "
                                         r".*later.21O for 2021-03-26 .* a navigation file of another day"):
        read_gnss_raw(later, nav)
    with pytest.raises(InputError, match="is a folder, not a file"):
        read_gnss_raw(tmp_path, nav)


def _code_fields_set_to(text, fill):
    """The RINEX 3 observation ``text`` with every code (pseudorange, type C..) field set to
    ``fill`` (right-aligned in its 14 columns; blank when empty)."""
    types, out, body, cur = {}, [], False, None
    for ln in text.splitlines(True):
        if not body:
            if ln[60:].startswith("SYS / # / OBS TYPES"):
                cur = ln[0] if ln[0] != " " else cur
                types[cur] = types.get(cur, []) + ln[7:60].split()
            body = "END OF HEADER" in ln[60:]
            out.append(ln)
            continue
        if ln[0] in types:
            row = list(ln.rstrip("\n"))
            for j, code in enumerate(types[ln[0]]):
                a = 3 + 16 * j
                if code.startswith("C") and a < len(row):
                    row[a:a + 14] = f"{fill:>14}"[: len(row) - a]
            ln = "".join(row) + "\n"
        out.append(ln)
    return "".join(out)


@needs_static
@pytest.mark.parametrize("fill, msg", [
    ("", r"60 epochs of raw observations without a single pseudorange \(every code observation empty or zero\)"),
    ("0.000", r"60 epochs of raw observations without a single pseudorange"),
    ("nan", r"every pseudorange is NaN \(1382 observations in 60 epochs\): the receiver reported no range"),
])
def test_no_pseudorange_in_any_epoch(tmp_path, fill, msg):
    """Every pseudorange empty, zero or NaN: said so, naming the file (it ended in 'no
    satellite has an ephemeris')."""
    from sinslab.data.gnss import read_gnss_raw

    obs = tmp_path / "noranges.21O"
    obs.write_text(_code_fields_set_to((STATIC / "SEPT078M1.21O").read_text(), fill))
    with pytest.raises(InputError, match="noranges.21O: " + msg):
        read_gnss_raw(obs, STATIC / "SEPT078M.21P")
