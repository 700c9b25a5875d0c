"""The Backlash (eq. 1) and Backlash-Inverse (eq. 2) operators, and Lemma 1, against hand-derived truth."""
import numpy as np
import pytest

from hwid.blocks.backlash import backlash, backlash_inverse, border_map

P = dict(slope_up=1.0, slope_down=1.0, d_plus=0.5, d_minus=-0.5)
PA = dict(slope_up=1.3, slope_down=0.7, d_plus=0.6, d_minus=-0.6)   # asymmetric; borders cross at u = 2


def test_horizontal_path_then_ascending_border():
    # start on the descending border at u = -1 (v = -0.5); rising u first moves v along a
    # horizontal path (v constant) until u - d+ reaches -0.5, i.e. u = 0, then v = u - d+.
    u = np.linspace(-1, 1.5, 251)
    v = backlash(u, **P, v0=-0.5)
    flat = u <= 0.0
    np.testing.assert_allclose(v[flat], -0.5, atol=0)
    np.testing.assert_allclose(v[~flat], u[~flat] - 0.5, atol=1e-15)


def test_closed_cycle_asymmetric():
    t = np.linspace(0, 4 * np.pi, 4001)
    u = 1.8 * np.sin(t)
    v = backlash(u, **PA)
    up, dn = PA["slope_up"] * (u - PA["d_plus"]), PA["slope_down"] * (u - PA["d_minus"])
    assert np.all(v >= up - 1e-12) and np.all(v <= dn + 1e-12)          # between the borders
    rising, falling = np.diff(u) > 0, np.diff(u) < 0
    dv = np.diff(v)
    on_up = np.isclose(v[1:], up[1:], atol=1e-12)
    on_dn = np.isclose(v[1:], dn[1:], atol=1e-12)
    # on a border v follows it with the border's slope; off the borders v is constant
    assert np.all(np.isclose(dv[rising & on_up & on_up[np.r_[0, :on_up.size - 1]]],
                             (PA["slope_up"] * np.diff(u))[rising & on_up & on_up[np.r_[0, :on_up.size - 1]]]))
    assert np.all(dv[~on_up & ~on_dn] == 0)
    # the second cycle visits both borders at the extremes: v(max u) on ascending, v(min u) on descending
    k_max, k_min = 2000 + np.argmax(u[2000:]), 2000 + np.argmin(u[2000:])
    assert v[k_max] == pytest.approx(up[k_max]) and v[k_min] == pytest.approx(dn[k_min])


def test_narrow_interval_reduces_to_horizontal_segment():
    # Fig. 6a: u oscillating inside [d-, d+] starting from v = 0 never reaches a border: v stays 0
    u = 0.4 * np.sin(np.linspace(0, 20, 2000))
    v = backlash(u, **P, v0=0.0)
    assert np.all(v == 0.0)


def test_backlash_inverse_eq2():
    z = np.array([0.0, 0.5, 1.0, 1.0, 0.6, 0.2, 0.2, 0.7])
    u = backlash_inverse(z, **PA, u0=0.0)
    Sa, Sd, dp, dm = PA["slope_up"], PA["slope_down"], PA["d_plus"], PA["d_minus"]
    expected = [0.0, 0.5 / Sa + dp, 1.0 / Sa + dp, 1.0 / Sa + dp, 0.6 / Sd + dm, 0.2 / Sd + dm,
                0.2 / Sd + dm, 0.7 / Sa + dp]
    np.testing.assert_allclose(u, expected, rtol=0, atol=1e-15)


@pytest.mark.parametrize("p", [P, PA])
def test_lemma1_backlash_of_inverse_is_identity(p):
    t = np.linspace(0, 30, 3001)
    z = np.sin(t) + 0.3 * np.sin(3.1 * t)
    u = backlash_inverse(z, **p, u0=z[0] / p["slope_up"] + p["d_plus"])
    v = backlash(u, **p, v0=z[0])
    np.testing.assert_allclose(v, z, atol=1e-12)


@pytest.mark.parametrize("p", [P, PA])
def test_lemma1_inverse_of_backlash_outside_gap_crossings(p):
    # B_inv(B(z)) equals z except while B crosses its gap after a reversal (B constant, B_inv holds):
    t = np.linspace(0, 30, 30001)
    z = 1.5 * np.sin(t)
    u = backlash(z, **p)
    v = backlash_inverse(u, **p)
    moving = np.r_[False, np.diff(u) != 0]
    first = np.argmax(moving)
    np.testing.assert_allclose(v[first:][moving[first:]], z[first:][moving[first:]], atol=1e-12)
    assert not np.allclose(v, z, atol=1e-3)           # the paper's claim fails during gap crossings


@pytest.mark.parametrize("p", [P, PA])
def test_border_map_is_right_inverse_of_backlash_inverse(p):
    t = np.linspace(0, 30, 3001)
    z = np.sin(t)
    u = border_map(z, **p, u0=p["slope_up"] * (z[0] - p["d_plus"]))   # start on the rising branch
    v = backlash_inverse(u, **p, u0=z[0])
    rev = np.r_[False, False, np.sign(np.diff(z[1:])) != np.sign(np.diff(z[:-1]))]
    ok = ~rev
    ok[0] = False
    np.testing.assert_allclose(v[ok], z[ok], atol=1e-12)
    n_extrema = int(np.floor((30 - np.pi / 2) / np.pi)) + 1          # sin has extrema at pi/2 + k pi
    assert rev.sum() == n_extrema
    # the one-sample switching transient: B_inv briefly reads the jump across the gap as motion
    Sa, Sd, dp, dm = p["slope_up"], p["slope_down"], p["d_plus"], p["d_minus"]
    top = z[rev] > 0
    glitch = np.where(top, Sd / Sa * (z[rev] - dm) + dp, Sa / Sd * (z[rev] - dp) + dm)
    np.testing.assert_allclose(v[rev], glitch, atol=1e-12)
