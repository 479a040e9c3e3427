"""Experiment design: the linearisation and modes, pulse widths, multisines and amplitudes of ``uavfmu excite``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fmu_models.common.model import derivative_function
from fmu_models.fixed_wing.linear import LATERAL, LONGITUDINAL, linearise, modes
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.fixed_wing.trim import trim
from identification.excite.design import (
    PULSES,
    ExciteError,
    ExciteOptions,
    assign_harmonics,
    multisine,
    plan_excitation,
    schroeder_phases,
    spectrum_centre,
)

AIRSPEED = 25.0


@pytest.fixture(scope="module")
def aerosonde():  # type: ignore[no-untyped-def]
    model = FixedWingModel()
    p = np.array(model.params.starts())
    tr = trim(model, p, AIRSPEED)
    return model, p, tr, linearise(model, p, tr)


def _euler_state(x_trim: np.ndarray, xr: np.ndarray) -> np.ndarray:
    """Full 16-state vector of the reduced state [u v w phi theta p q r] (heading 0, trim position)."""
    phi, theta = xr[3], xr[4]
    cr, sr, cp, sp = math.cos(phi / 2), math.sin(phi / 2), math.cos(theta / 2), math.sin(theta / 2)
    q = [cr * cp, sr * cp, cr * sp, -sr * sp]
    return np.array([*x_trim[0:3], *xr[0:3], *q, *xr[5:8], *x_trim[13:16]])


def test_jacobian_matches_finite_differences_of_the_nonlinear_model(aerosonde) -> None:  # type: ignore[no-untyped-def]
    model, p, tr, lin = aerosonde
    f = derivative_function(model)

    def reduced(xr: np.ndarray, u: np.ndarray) -> np.ndarray:
        xd = np.asarray(f(_euler_state(tr.x, xr), u, p)).ravel()
        phi, theta = xr[3], xr[4]
        pr, qr, rr = xr[5:8]
        return np.array([*xd[3:6], pr + math.tan(theta) * (qr * math.sin(phi) + rr * math.cos(phi)),
                         qr * math.cos(phi) - rr * math.sin(phi), *xd[10:13]])

    h = 1e-6
    A_fd = np.column_stack([(reduced(lin.x_trim + h * e, tr.u) - reduced(lin.x_trim - h * e, tr.u)) / (2 * h)
                            for e in np.eye(8)])
    B_fd = np.column_stack([(reduced(lin.x_trim, tr.u + h * e) - reduced(lin.x_trim, tr.u - h * e)) / (2 * h)
                            for e in np.eye(4)])
    np.testing.assert_allclose(lin.A, A_fd, atol=1e-4 * np.abs(A_fd).max())
    np.testing.assert_allclose(lin.B, B_fd, atol=1e-4 * np.abs(B_fd).max())
    # at trim the longitudinal derivatives vanish to the trim's least-squares residual (< 1e-4 m/s2, rad/s2)
    assert np.linalg.norm(reduced(lin.x_trim, tr.u)[[0, 2, 6]]) < 1e-4


def test_roll_damping_and_roll_mode_follow_the_textbook_formula(aerosonde) -> None:  # type: ignore[no-untyped-def]
    """Beard & McLain eqs. 3.13 and 5.x: ``L_p = qbar S b (b / 2Va) (Γ3 C_ell_p + Γ4 C_n_p)``; the roll
    subsidence eigenvalue is close to ``L_p`` (the one-degree-of-freedom roll approximation)."""
    model, p, tr, lin = aerosonde
    pv = model.params.view(p)
    _, va, _, _, rho = model.air_data(tr.x, p)
    va, rho = float(va), float(rho)
    gam = pv.Jx_kg_m2 * pv.Jz_kg_m2 - pv.Jxz_kg_m2 ** 2
    g3, g4 = pv.Jz_kg_m2 / gam, pv.Jxz_kg_m2 / gam
    l_p = 0.5 * rho * va ** 2 * pv.S_wing_m2 * pv.b_m * pv.b_m / (2 * va) * (g3 * pv.C_ell_p + g4 * pv.C_n_p)
    assert lin.A[5, 5] == pytest.approx(l_p, rel=1e-6)
    m = modes(lin)
    assert m.roll_subsidence.eigenvalues[0].real == pytest.approx(l_p, rel=0.1)
    assert m.roll_subsidence.time_constant_s == pytest.approx(-1 / m.roll_subsidence.eigenvalues[0].real)


def test_modes_are_classified_from_the_decoupled_sets(aerosonde) -> None:  # type: ignore[no-untyped-def]
    _, _, _, lin = aerosonde
    m = modes(lin)
    lon = np.linalg.eigvals(lin.sub(LONGITUDINAL)[0])
    lat = np.linalg.eigvals(lin.sub(LATERAL)[0])
    # every eigenvalue of each set appears in exactly one mode
    got_lon = sorted(m.short_period.eigenvalues + m.phugoid.eigenvalues, key=lambda e: (e.real, e.imag))
    np.testing.assert_allclose(got_lon, sorted(lon, key=lambda e: (e.real, e.imag)))
    got_lat = m.roll_subsidence.eigenvalues + m.dutch_roll.eigenvalues + m.spiral.eigenvalues
    np.testing.assert_allclose(sorted(got_lat, key=lambda e: (e.real, e.imag)),
                               sorted(lat, key=lambda e: (e.real, e.imag)))
    assert m.short_period.wn_rad_s > 3 * m.phugoid.wn_rad_s  # short period fast, phugoid slow
    assert m.roll_subsidence.wn_rad_s > m.dutch_roll.wn_rad_s > m.spiral.wn_rad_s
    assert abs(m.dutch_roll.eigenvalues[0].imag) > 0  # the Aerosonde's Dutch roll oscillates
    for md in (m.short_period, m.phugoid, m.dutch_roll):  # wn, zeta describe the pair exactly
        e = md.eigenvalues[0]
        assert abs(e) == pytest.approx(md.wn_rad_s) and -e.real / abs(e) == pytest.approx(md.zeta)
    # the full 8-state eigenvalues are those of the two sets (wings-level trim decouples them)
    full = np.sort_complex(np.linalg.eigvals(lin.A))
    np.testing.assert_allclose(full, np.sort_complex(np.concatenate([lon, lat])), atol=0.05)


def test_doublet_spectrum_peak_and_design_centres() -> None:
    # |U(jw)| of a doublet ~ sin^2(x/2)/x peaks where tan(x/2) = x (x = w dt): x = 2.331 (Jategaonkar's 2.3/wn)
    x = np.linspace(0.5, 4.0, 400001)
    peak = x[np.argmax(np.sin(x / 2) ** 4 / x ** 2)]
    assert peak == pytest.approx(2.331, abs=2e-3)
    assert spectrum_centre(PULSES["doublet"]) == pytest.approx(2.04, abs=0.01)
    assert spectrum_centre(PULSES["3211"]) == pytest.approx(0.86, abs=0.01)


def test_pulse_widths_follow_the_modes() -> None:
    opt = ExciteOptions(inputs=("3211", "doublet"), min_pulse_s=0.02, max_frequency_hz=50.0, rate_hz=400.0)
    plan = plan_excitation(None, opt)
    for b in (b for b in plan.blocks if b.axis != "throttle"):
        w = plan.targets_rad_s[b.axis]
        assert b.pulse_unit_s == pytest.approx(spectrum_centre(PULSES[b.input]) / w, abs=0.5 / opt.rate_hz)
    assert plan.targets_rad_s["rudder"] == pytest.approx(plan.modes.dutch_roll.wn_rad_s)
    assert plan.targets_rad_s["elevator"] == pytest.approx(plan.modes.short_period.wn_rad_s)
    assert plan.targets_rad_s["aileron"] == pytest.approx(plan.modes.roll_subsidence.wn_rad_s)
    # the default floor: no pulse shorter than min_pulse_s, and the aileron target capped at max_frequency_hz
    default = plan_excitation()
    assert min(b.pulse_unit_s for b in default.blocks if b.pulse_unit_s) >= 0.1 - 1e-9
    assert default.targets_rad_s["aileron"] == pytest.approx(2 * math.pi * 3.0)


def test_throttle_doublets_at_attitude_hold_alternate_and_stay_within_the_throttle_range() -> None:
    from identification.excite.design import throttle_pulse

    plan = plan_excitation()
    thr = [b for b in plan.blocks if b.axis == "throttle"]
    assert len(thr) == 2 and all(b.input == "doublet" and set(b.signals) == {"throttle"} for b in thr)
    first = [sig.steps[0][1] for b in thr for sig in b.signals.values()]
    assert first[0] == -first[1] and abs(first[0]) <= 0.2 + 1e-12  # alternating sign, within the amplitude
    assert all(b.pulse_unit_s == pytest.approx(2.0) for b in thr)
    assert 0 < plan.trim.throttle - abs(first[0]) and plan.trim.throttle + abs(first[0]) < 1
    du = plan.deflection(np.array([thr[0].excitation_start_s + 0.5]))[0]
    assert du[3] == pytest.approx(first[0]) and not du[:3].any()  # only the throttle moves
    # 0: the doublet's spectrum centre on the phugoid, at least 2 s
    opt = ExciteOptions(throttle_pulse_s=0.0)
    want = max(2.0, spectrum_centre(PULSES["doublet"]) / plan.modes.phugoid.wn_rad_s)
    assert throttle_pulse(plan.modes, opt) == pytest.approx(want, abs=0.5 / opt.rate_hz)
    assert not [b for b in plan_excitation(None, ExciteOptions(throttle_blocks=0)).blocks if b.axis == "throttle"]


def test_schroeder_multisine_is_orthogonal_low_peak_and_starts_at_zero() -> None:
    bands = {"aileron": (5.0, 19.0), "elevator": (3.0, 19.0), "rudder": (1.4, 12.0)}
    period = 10.0
    harm = assign_harmonics(bands, period)
    ks = [k for v in harm.values() for k in v]
    assert len(ks) == len(set(ks)) and all(harm.values())  # disjoint, none empty
    for s, k in harm.items():
        w = 2 * math.pi * np.asarray(k) / period
        assert np.all((w >= bands[s][0]) & (w <= bands[s][1]))
    t = np.arange(0.0, period, 0.001)
    sig = {s: multisine(k, period, period) for s, k in harm.items()}
    u = {s: g(t) for s, g in sig.items()}
    for a in u:
        assert np.max(np.abs(u[a])) == pytest.approx(1.0, rel=1e-3)  # unit peak
        assert abs(u[a][0]) < 1e-3 and abs(sig[a](np.array([period - 1e-9]))[0]) < 0.05  # starts/ends ~0
        for b in u:
            if a < b:  # mutually orthogonal over the period
                assert abs(np.mean(u[a] * u[b])) < 1e-3 * np.sqrt(np.mean(u[a] ** 2) * np.mean(u[b] ** 2)) * 10
    # Schroeder phases: far lower peak factor than all-zero phases (sqrt(2 n) for n equal cosines)
    k = list(range(5, 25))
    w = 2 * math.pi * np.asarray(k) / period
    zero = np.cos(np.outer(t, w)).sum(axis=1)
    schr = np.cos(np.outer(t, w) + schroeder_phases(len(k))).sum(axis=1)
    rms = math.sqrt(len(k) / 2)
    assert np.max(np.abs(zero)) / rms == pytest.approx(math.sqrt(2 * len(k)), rel=1e-3)
    assert np.max(np.abs(schr)) / rms < 0.4 * np.max(np.abs(zero)) / rms


def test_amplitudes_respect_surface_and_attitude_limits() -> None:
    opt = ExciteOptions(roll_limit_deg=30.0, pitch_limit_deg=10.0, surface_limit_deg=15.0)
    plan = plan_excitation(None, opt)
    trim_deg = {"aileron": plan.trim.aileron_rad, "elevator": plan.trim.elevator_rad, "rudder": plan.trim.rudder_rad}

    def cap(s: str) -> float:  # throttle: a fraction of full throttle within [0, 1] about the trim throttle
        if s == "throttle":
            return min(opt.throttle_amplitude, opt.surface_margin * min(plan.trim.throttle, 1 - plan.trim.throttle))
        return opt.surface_margin * (math.radians(opt.surface_limit_deg) - abs(trim_deg[s]))

    for b in plan.blocks:
        for s, sig in b.signals.items():
            assert 0 < sig.peak_rad() <= cap(s) * (1 + 1e-9)
        assert b.predicted_peak_deg["roll"] <= opt.attitude_fraction * opt.roll_limit_deg * (1 + 1e-9)
        assert b.predicted_peak_deg["pitch"] <= opt.attitude_fraction * opt.pitch_limit_deg * (1 + 1e-9)
        # one limit is active: the amplitude is as large as the limits allow
        assert (max(b.predicted_peak_deg["roll"] / (opt.attitude_fraction * opt.roll_limit_deg),
                    b.predicted_peak_deg["pitch"] / (opt.attitude_fraction * opt.pitch_limit_deg)) > 0.999
                or any(sig.peak_rad() >= 0.999 * cap(s) for s, sig in b.signals.items()))
    # blocks are in order, each with its settle, input and recovery
    for a, b in zip(plan.blocks, plan.blocks[1:], strict=False):
        assert a.start_s < a.excitation_start_s < a.end_s < b.start_s
        assert b.start_s - a.end_s == pytest.approx(opt.recovery_s)


def test_user_parameter_file_gives_its_own_modes(tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "plane.json"
    path.write_text('{"mass_kg": 2.0, "Jx_kg_m2": 0.05, "Jy_kg_m2": 0.08, "Jz_kg_m2": 0.12, "Jxz_kg_m2": 0.0,'
                    ' "S_wing_m2": 0.45, "b_m": 1.88, "c_m": 0.24}')
    small = plan_excitation(FixedWingParams.load(path), ExciteOptions(airspeed_m_s=25.0))
    big = plan_excitation(None, ExciteOptions(airspeed_m_s=25.0))
    assert small.modes.roll_subsidence.wn_rad_s != pytest.approx(big.modes.roll_subsidence.wn_rad_s, rel=0.1)
    assert small.modes.short_period.wn_rad_s != pytest.approx(big.modes.short_period.wn_rad_s, rel=0.1)
    rudder = next(b.pulse_unit_s for b in small.blocks if b.axis == "rudder" and b.input == "doublet")
    assert rudder == pytest.approx(spectrum_centre(PULSES["doublet"]) / small.modes.dutch_roll.wn_rad_s, abs=0.011)


@pytest.mark.parametrize("kw, text", [({"roll_limit_deg": 100.0}, "roll_limit_deg = 100.0; allowed range [5.0, 80.0]"),
                                      ({"inputs": ("chirp",)}, "inputs: 'chirp' unknown"),
                                      ({"rate_hz": True}, "rate_hz = True"),
                                      ({"airspeed_m_s": 2.0}, "airspeed_m_s = 2.0")])
def test_bad_options_are_named_with_their_range(kw: dict, text: str) -> None:
    with pytest.raises(ExciteError, match=None) as err:
        plan_excitation(None, ExciteOptions(**kw))
    assert text in str(err.value)


def test_multisine_band_without_harmonics_is_refused() -> None:
    with pytest.raises(ExciteError, match="no harmonic"):
        plan_excitation(None, ExciteOptions(inputs=("multisine",), multisine_period_s=2.0, band_low=0.9,
                                            band_high=1.05, surfaces=("rudder",)))
