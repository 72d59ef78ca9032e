"""Independent checks of the attitude convention: explicit matrices, round trips, NED/FRD."""
import math

import numpy as np
import pytest

from sinslab.core import attitude as at

D = math.pi / 180


def Rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def Ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def Rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def random_att(rng, n):
    """Random [pitch, roll, yaw] away from the pitch singularity."""
    return np.column_stack([rng.uniform(-85, 85, n) * D, rng.uniform(-179, 179, n) * D,
                            rng.uniform(-179, 179, n) * D])


RNG = np.random.default_rng(20240601)
ATTS = random_att(RNG, 200)


def test_convention_explicit_matrices():
    for p, r, y in ATTS[:50]:
        C = Rz(y) @ Rx(p) @ Ry(r)
        assert np.allclose(at.euler_to_dcm([p, r, y]), C, atol=1e-14)
    # element-wise closed form of C_b^n = Rz(ψ) Rx(θ) Ry(γ)
    p, r, y = 0.3, -0.7, 2.1
    cp, sp, cr, sr, cy, sy = math.cos(p), math.sin(p), math.cos(r), math.sin(r), math.cos(y), math.sin(y)
    C = np.array([[cy * cr - sy * sp * sr, -sy * cp, cy * sr + sy * sp * cr],
                  [sy * cr + cy * sp * sr, cy * cp, sy * sr - cy * sp * cr],
                  [-cp * sr, sp, cp * cr]])
    assert np.allclose(at.euler_to_dcm([p, r, y]), C, atol=1e-15)
    # vectorised shapes
    assert at.euler_to_dcm(ATTS.reshape(20, 10, 3)).shape == (20, 10, 3, 3)


def test_single_axis_meanings():
    """Positive yaw turns the nose left (CCW), positive pitch raises it, positive roll drops the right wing."""
    # yaw +90° (CCW about up): forward (body y) points west
    C = at.euler_to_dcm([0, 0, 90 * D])
    assert np.allclose(C @ [0, 1, 0], [-1, 0, 0], atol=1e-15)
    assert at.yaw_to_heading(90 * D) == pytest.approx(270 * D)
    # pitch +10°: nose up, forward has a positive up component
    C = at.euler_to_dcm([10 * D, 0, 0])
    assert np.allclose(C @ [0, 1, 0], [0, math.cos(10 * D), math.sin(10 * D)], atol=1e-15)
    # roll +5° about forward (y): right wing (x) goes down
    C = at.euler_to_dcm([0, 5 * D, 0])
    assert (C @ [1, 0, 0])[2] == pytest.approx(-math.sin(5 * D))


def test_aircraft_heading_east_nose_up_right_wing_down():
    """Heading 90° (east), pitch 10° nose up, right wing down 5°: body axes in ENU."""
    th, ga = 10 * D, 5 * D
    att = np.array([th, ga, at.heading_to_yaw(90 * D)])
    assert att[2] == pytest.approx(-90 * D)
    C = at.euler_to_dcm(att)
    fwd, right, up = C[:, 1], C[:, 0], C[:, 2]
    # nose points east and up by 10°
    assert np.allclose(fwd, [math.cos(th), 0, math.sin(th)], atol=1e-15)
    # right wing points south, tilted down by 5°: right = Rz(-90)Rx(θ)Ry(γ) x
    assert right[1] < 0 and right[2] == pytest.approx(-math.sin(ga) * math.cos(th))
    assert np.allclose(right, [math.sin(ga) * math.sin(th), -math.cos(ga), -math.sin(ga) * math.cos(th)],
                       atol=1e-15)
    # roof (up) is tilted: it leans back (west) with pitch and to the right (south) with roll
    assert up[2] == pytest.approx(math.cos(th) * math.cos(ga))
    assert up[0] < 0 and up[1] < 0
    assert np.allclose(up, [-math.sin(th) * math.cos(ga), -math.sin(ga), math.cos(th) * math.cos(ga)],
                       atol=1e-15)
    assert np.allclose(np.cross(right, fwd), up, atol=1e-15)          # right-handed
    # the same attitude in NED/FRD: roll 5° right wing down (+), pitch 10°, yaw 90° (east)
    rpy = at.euler_to_ned(att)
    assert np.allclose(rpy, [ga, th, 90 * D], atol=1e-13)
    assert np.allclose(at.euler_from_ned(rpy), att, atol=1e-13)
    # NED body axes: FRD x forward = NED of our forward
    Cn = at.dcm_to_ned(C)
    assert np.allclose(Cn[:, 0], at.vec_enu_to_ned(fwd), atol=1e-15)
    assert np.allclose(Cn[:, 1], at.vec_enu_to_ned(right), atol=1e-15)
    assert np.allclose(Cn[:, 2], at.vec_enu_to_ned(-up), atol=1e-15)


def test_dcm_to_euler_round_trip():
    C = at.euler_to_dcm(ATTS)
    assert np.allclose(at.dcm_to_euler(C), ATTS, atol=1e-12)
    assert np.allclose(C @ np.swapaxes(C, -1, -2), np.eye(3), atol=1e-14)
    assert np.allclose(np.linalg.det(C), 1.0)


def test_quat_round_trips():
    q = at.euler_to_quat(ATTS)
    assert np.allclose(np.linalg.norm(q, axis=-1), 1.0)
    assert np.all(q[:, 0] >= 0)
    assert np.allclose(at.quat_to_euler(q), ATTS, atol=1e-12)
    assert np.allclose(at.quat_to_dcm(q), at.euler_to_dcm(ATTS), atol=1e-14)
    assert np.allclose(at.dcm_to_quat(at.euler_to_dcm(ATTS)), q, atol=1e-14)
    # the quaternion rotates body vectors into n: q ⊗ [0 v] ⊗ q* == C v
    v = RNG.normal(size=(len(q), 3))
    qv = at.quat_mul(at.quat_mul(q, np.column_stack([np.zeros(len(q)), v])), at.quat_conj(q))
    assert np.allclose(qv[:, 1:], np.einsum("nij,nj->ni", at.euler_to_dcm(ATTS), v), atol=1e-13)
    # composition: C(p ⊗ q) = C(p) C(q)
    p = at.euler_to_quat(ATTS[::-1])
    assert np.allclose(at.quat_to_dcm(at.quat_mul(p, q)), at.quat_to_dcm(p) @ at.quat_to_dcm(q), atol=1e-13)


def _bits(a):
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


def test_closed_forms_equal_scipy_rotation_to_the_bit():
    """euler_to_dcm, euler_to_quat and quat_to_dcm are closed forms (a navigation never
    imports scipy.spatial); they must give scipy's ``Rotation`` bits, signed zeros included,
    so that replacing one by the other changes no output."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(7)
    edge = np.array([0.0, -0.0, math.pi, -math.pi, math.pi / 2, -math.pi / 2, 1e-300, -1e-17])
    att = np.concatenate([rng.uniform(-4, 4, (20000, 3)),
                          np.stack(np.meshgrid(edge, edge, edge), -1).reshape(-1, 3)])
    ref = Rotation.from_euler("ZXY", att[:, [2, 0, 1]])
    assert np.array_equal(_bits(at.euler_to_dcm(att)), _bits(ref.as_matrix()))
    q_ref = ref.as_quat()[:, [3, 0, 1, 2]]
    q_ref *= np.where(q_ref[:, :1] < 0, -1.0, 1.0)
    assert np.array_equal(_bits(at.euler_to_quat(att)), _bits(q_ref))
    # one attitude (no leading axis) is the same computation
    assert np.array_equal(_bits(at.euler_to_dcm(att[5])), _bits(ref[5].as_matrix()))
    q = np.concatenate([rng.normal(size=(20000, 4)) * rng.uniform(1e-3, 1e3, (20000, 1)),
                        np.eye(4), -np.eye(4)])
    assert np.array_equal(_bits(at.quat_to_dcm(q)),
                          _bits(Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()))
    with pytest.raises(ValueError, match="zero norm"):
        at.quat_to_dcm([0.0, 0.0, 0.0, 0.0])
    # euler_from_ned's 3-2-1 closed form against scipy's from_euler("ZYX")
    rpy = att[:, [1, 0, 2]]
    C_ned = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()
    assert np.array_equal(_bits(at.euler_from_ned(rpy)), _bits(at.dcm_to_euler(at.dcm_from_ned(C_ned))))
    assert np.array_equal(_bits(at.euler_from_ned(rpy[7])), _bits(at.dcm_to_euler(at.dcm_from_ned(C_ned[7]))))


def test_rotvec_round_trips():
    r = RNG.normal(size=(200, 3))
    r *= (RNG.uniform(0, 3.1, 200) / np.linalg.norm(r, axis=1))[:, None]
    C = at.rotvec_to_dcm(r)
    assert np.allclose(at.dcm_to_rotvec(C), r, atol=1e-12)
    assert np.allclose(at.quat_to_rotvec(at.rotvec_to_quat(r)), r, atol=1e-12)
    assert np.allclose(at.quat_to_dcm(at.rotvec_to_quat(r)), C, atol=1e-14)
    # Rodrigues by hand: exp(r×) = I + sin|r| (u×) + (1 − cos|r|) (u×)²
    for ri in r[:20]:
        n = np.linalg.norm(ri)
        K = at.skew(ri / n)
        assert np.allclose(at.rotvec_to_dcm(ri), np.eye(3) + math.sin(n) * K + (1 - math.cos(n)) * K @ K,
                           atol=1e-14)
    # a rotation about up by +a is yaw +a
    assert np.allclose(at.rotvec_to_dcm([0, 0, 0.4]), at.euler_to_dcm([0, 0, 0.4]), atol=1e-15)


def test_skew():
    a, b = RNG.normal(size=(2, 10, 3))
    assert np.allclose(np.einsum("nij,nj->ni", at.skew(a), b), np.cross(a, b))
    assert np.allclose(at.skew(a[0]), -at.skew(a[0]).T)


def test_numba_kernels_match_numpy():
    for p, r, y in ATTS[:60]:
        q = np.array(at.euler2q_s(p, r, y))
        q_np = at.euler_to_quat([p, r, y])
        assert np.allclose(q * np.sign(q[0]), q_np, atol=1e-14)
        C = np.array(at.q2dcm_s(*q)).reshape(3, 3)
        assert np.allclose(C, at.euler_to_dcm([p, r, y]), atol=1e-14)
        assert np.allclose(at.q2euler_s(*q), [p, r, y], atol=1e-12)
    for ri in RNG.normal(size=(30, 3)):
        a, b = np.array(at.rv2q_s(*ri)), at.rotvec_to_quat(ri)
        assert np.allclose(a, b, atol=1e-14) or np.allclose(a, -b, atol=1e-14)   # q and −q: same rotation
    # small-angle branch of rv2q_s
    tiny = np.array([1e-9, -2e-9, 3e-9])
    assert np.allclose(at.rv2q_s(*tiny), at.rotvec_to_quat(tiny), atol=1e-18)
    a, b = at.euler_to_quat(ATTS[:2])
    assert np.allclose(at.qmul_s(*a, *b), at.quat_mul(a, b), atol=1e-15)


def test_rv2q_s_series_agrees_with_the_closed_form_to_rounding():
    """Below 1e-3 rad rv2q_s takes the closed form's Taylor series to n⁴ (the dropped terms
    < 1e-22): it agrees with cos(n/2), sin(n/2)/n·r to the rounding of either, on both
    sides of the switch."""
    import math

    for n in np.geomspace(1e-9, 3e-3, 60):
        for r in RNG.normal(size=(3, 3)):
            v = n * r / np.linalg.norm(r)
            s = math.sin(0.5 * n) / n
            exact = np.array([math.cos(0.5 * n), *(v * s)])
            np.testing.assert_allclose(at.rv2q_s(*v), exact, rtol=0, atol=3e-16)


def test_q2euler_s_clamps_at_the_pitch_singularity():
    q = at.euler2q_s(90 * D, 0.0, 0.3)
    p, r, y = at.q2euler_s(*q)
    assert math.isfinite(p) and p == pytest.approx(90 * D, abs=1e-6)


def test_misalignment_round_trip_and_sign():
    C = at.euler_to_dcm(ATTS[:50])
    phi = RNG.normal(size=(50, 3)) * 10 * D / 60
    Cc = at.apply_misalignment(C, phi)
    assert np.allclose(at.misalignment(C, Cc), phi, atol=1e-13)
    # small-angle definition: C' ≈ (I − φ×) C
    small = np.array([1e-5, -2e-5, 3e-5])
    Cc = at.apply_misalignment(C[0], small)
    assert np.allclose(Cc, (np.eye(3) - at.skew(small)) @ C[0], atol=1e-9)
    # a positive φU (computed frame rotated CCW about up relative to true n) = yaw error −φU
    C0 = at.euler_to_dcm([0, 0, 0.2])
    Cc = at.apply_misalignment(C0, [0, 0, 1e-3])
    assert at.dcm_to_euler(Cc)[2] == pytest.approx(0.2 - 1e-3, abs=1e-12)


def test_heading_yaw():
    assert at.heading_to_yaw(0.0) == 0.0
    assert at.heading_to_yaw(90 * D) == pytest.approx(-90 * D)
    assert at.heading_to_yaw(235 * D) == pytest.approx(125 * D)            # paper 000 heading
    assert at.heading_to_yaw(180 * D) == pytest.approx(180 * D)            # (−π, π]
    h = RNG.uniform(0, 2 * math.pi, 100)
    assert np.allclose(at.yaw_to_heading(at.heading_to_yaw(h)), h, atol=1e-12)
    assert np.all((at.yaw_to_heading(ATTS[:, 2]) >= 0) & (at.yaw_to_heading(ATTS[:, 2]) < 2 * math.pi))
    assert np.allclose(at.wrap_pi([3 * math.pi, -math.pi, math.pi + 0.1]), [math.pi, math.pi, -math.pi + 0.1])


def test_wrap_pi_scalar_form_agrees_and_is_exact_inside():
    """wrap_pi_s (compiled) equals wrap_pi to rounding, lands in (−π, π], and leaves an
    angle inside the interval untouched."""
    a = np.r_[RNG.uniform(-40, 40, 2000), [math.pi, -math.pi, 3 * math.pi, -3 * math.pi, 0.0, 1e-300]]
    s = np.array([at.wrap_pi_s(v) for v in a])
    assert np.all((s > -math.pi) & (s <= math.pi))
    assert np.allclose(s, at.wrap_pi(a), rtol=0, atol=4 * np.spacing(40.0))
    inside = (a > -math.pi) & (a <= math.pi)
    assert np.array_equal(s[inside], a[inside])


def test_ned_conversions():
    assert np.allclose(at.M_ENU_NED @ at.M_ENU_NED, np.eye(3))
    v = RNG.normal(size=(5, 3))
    assert np.allclose(at.vec_ned_to_enu(v), v @ at.M_ENU_NED.T)
    assert np.allclose(at.vec_enu_to_ned(at.vec_ned_to_enu(v)), v)
    # north in NED [1,0,0] is [0,1,0] in ENU; down is −up
    assert np.allclose(at.vec_ned_to_enu([1, 0, 0]), [0, 1, 0])
    assert np.allclose(at.vec_ned_to_enu([0, 0, 1]), [0, 0, -1])
    C = at.euler_to_dcm(ATTS[:30])
    assert np.allclose(at.dcm_from_ned(at.dcm_to_ned(C)), C, atol=1e-15)
    rpy = at.euler_to_ned(ATTS[:30])
    assert np.allclose(at.euler_from_ned(rpy), ATTS[:30], atol=1e-12)
    # NED yaw is the heading (clockwise from north), pitch and roll the same as ours
    hd = at.yaw_to_heading(ATTS[:30, 2])
    assert np.allclose(np.mod(rpy[:, 2], 2 * math.pi), hd, atol=1e-12)
    assert np.allclose(rpy[:, 1], ATTS[:30, 0], atol=1e-12) and np.allclose(rpy[:, 0], ATTS[:30, 1], atol=1e-12)
    # explicit aerospace 3-2-1 for one case
    r, p, y = 0.1, 0.2, 0.3
    Cned = Rz(y) @ Ry(p) @ Rx(r)
    assert np.allclose(at.dcm_from_ned(Cned), at.euler_to_dcm(at.euler_from_ned([r, p, y])), atol=1e-14)


def test_scalar_euler_dcm_and_body_rate_kernels():
    """euler_dcm_sc equals euler_to_dcm; euler_rates_to_body_sc is the body rate of the
    Euler-angle motion: (ω_nb^b ×) = C^T dC/dt, checked by central differences."""
    from sinslab.core.attitude import euler_dcm_sc, euler_rates_to_body_sc, euler_to_dcm

    rng = np.random.default_rng(7)

    def C_of(a):
        s, c = np.sin(a), np.cos(a)
        return np.array(euler_dcm_sc(s[0], c[0], s[1], c[1], s[2], c[2])).reshape(3, 3)

    for _ in range(20):
        att = rng.uniform([-1.4, -3.1, -3.1], [1.4, 3.1, 3.1])
        rate = rng.normal(0, 0.5, 3)                     # [pitch, roll, yaw] rates, rad/s
        np.testing.assert_allclose(C_of(att), euler_to_dcm(att), atol=1e-15)
        h = 1e-6
        Cd = (C_of(att + rate * h) - C_of(att - rate * h)) / (2 * h)
        W = C_of(att).T @ Cd
        w_fd = np.array([W[2, 1], W[0, 2], W[1, 0]])
        s, c = np.sin(att), np.cos(att)
        w = euler_rates_to_body_sc(s[0], c[0], s[1], c[1], rate[0], rate[1], rate[2])
        np.testing.assert_allclose(w, w_fd, atol=1e-8)


def test_wrap_pi_float_is_wrap_pi_bit_for_bit():
    """wrap_pi_float (Python floats) gives wrap_pi's bits: Python's float % and numpy's mod
    are one algorithm (fmod, the divisor added when the signs differ, a zero signed as the
    divisor), over random angles, the interval ends and their neighbours, zeros and huge values."""
    ends = [math.pi, -math.pi, 2 * math.pi, -2 * math.pi, 3 * math.pi]
    a = np.r_[RNG.uniform(-40, 40, 20000), RNG.normal(0, 1e6, 2000), ends,
              [math.nextafter(v, w) for v in ends for w in (-math.inf, math.inf)],
              [0.0, -0.0, 1e-300, -1e-300, 1e300, -1e300]]
    got = np.array([at.wrap_pi_float(v) for v in a])
    assert np.array_equal(got.view(np.int64), at.wrap_pi(a).view(np.int64))
    assert all(type(at.wrap_pi_float(v)) is float for v in (np.float64(4.0), 4.0, 4))
