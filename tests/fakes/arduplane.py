"""A fake ArduPlane landing: the longitudinal structure of ArduPlane 4.x's automatic landing (AP_TECS energy
control, AP_Landing's flare trigger and flare sink-rate demand, AP_PitchController / AP_RollController attitude
to rate loops) flown on the fixed-wing FMU through the adapter's PWM mapping, from a trimmed glide path to
touchdown. Simplified where the landing does not depend on it: no navigation (the approach is a straight line
north along the glide path, wings held level), no sensor noise, TECS's airspeed and climb-rate filters replaced
by the FMU's true values, ArduPilot defaults for every TECS gain the generated file leaves at its default
(TECS_THR_DAMP 0.5, TECS_PTCH_DAMP 0.3, TECS_LAND_DAMP 0.5, TECS_INTEG_GAIN 0.3, TECS_VERT_ACC 7,
TECS_FLARE_HGT 1, TECS_LAND_SPDWGT -1: speed weight sliding from 1 to 0 along the approach)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

G = 9.80665  #: AP's GRAVITY_MSS
FULL_DEG = 45.0  #: ArduPilot's surface output range (+-45 degrees of the servo throw)
DEG = 180.0 / math.pi
SERVO_TAU_S = 0.05
#: ArduPilot defaults the generated file does not set (AP_TECS.cpp / AP_Landing.cpp var_info)
DEFAULTS = {"TECS_THR_DAMP": 0.5, "TECS_PTCH_DAMP": 0.3, "TECS_LAND_DAMP": 0.5, "TECS_INTEG_GAIN": 0.3,
            "TECS_VERT_ACC": 7.0, "TECS_FLARE_HGT": 1.0, "TECS_LAND_PMAX": 10.0, "LAND_PITCH_DEG": 0.0,
            "LAND_FLARE_ALT": 3.0, "LAND_FLARE_SEC": 2.0, "TECS_LAND_SINK": 0.25}


@dataclass
class Landing:
    """What the fake landing did: per control step (50 Hz) the time [s], distance flown north [m], height [m],
    climb rate [m/s], airspeed [m/s], pitch [deg], throttle, flaring; and the touchdown."""

    rows: list[tuple[float, ...]] = field(default_factory=list)
    touchdown_sink_m_s: float = math.nan
    touchdown_airspeed_m_s: float = math.nan
    touchdown_north_m: float = math.nan
    flare_height_m: float = math.nan

    @property
    def array(self) -> np.ndarray:
        return np.array(self.rows)


def fly_landing(fmu: Path, params: dict[str, float], glide_deg: float, start_height_m: float = 30.0,
                max_s: float = 60.0, dt: float = 0.02) -> Landing:
    """Fly the final approach on the glide path of ``glide_deg`` (degrees below the horizon) at TECS_LAND_ARSPD
    from ``start_height_m`` to touchdown, with the ArduPlane parameters ``params``; the landing point is where
    the glide path meets the ground."""
    from fmu_models.fixed_wing.trim import trim
    from fmu_models.fmi.host import FmuHost
    from fmu_models.signals.pwm_mapping import default_mapping
    from hil_adapter.autopilot_params import _simulator, fmu_parameters

    v = {**DEFAULTS, **params}
    sim, p = _simulator("fixed_wing", fmu_parameters(fmu))
    v_app = v["TECS_LAND_ARSPD"]
    gamma = -math.radians(glide_deg)
    t0 = trim(sim.model, p, v_app, gamma)
    channels = {c.target: c for c in default_mapping("fixed_wing").channels}

    def surface(name: str, out_deg: float) -> float:
        """ArduPilot's +-45 output -> SERVO PWM around trim -> the adapter's mapping -> FMU input."""
        c = channels[name]
        out_deg = min(max(out_deg, -FULL_DEG), FULL_DEG)
        half = (c.max_us - c.trim_us) if out_deg >= 0 else (c.trim_us - c.min_us)
        return c.to_input(c.trim_us + out_deg / FULL_DEG * half)

    def out_of(name: str, deflection: float) -> float:
        """The +-45 output that gives ``deflection`` (to start the integrators at trim)."""
        lo, hi = -FULL_DEG, FULL_DEG
        rising = surface(name, 10.0) > surface(name, 0.0)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if (surface(name, mid) < deflection) == rising:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

    x_land = start_height_m / math.tan(-gamma)
    host = FmuHost(fmu)
    host.start({"init_vel_body_x_m_s": v_app * math.cos(t0.alpha_rad),
                "init_vel_body_z_m_s": v_app * math.sin(t0.alpha_rad),
                "init_pitch_rad": t0.alpha_rad + gamma, "init_pos_down_m": -start_height_m})
    on_ground_vr = host.refs(["on_ground"])
    names = ["altitude_m", "vel_down_m_s", "airspeed_m_s", "pitch_rad", "roll_rad", "rate_body_x_rad_s",
             "rate_body_y_rad_s", "pos_north_m"]
    # TECS constants
    stedot_max, stedot_min = v["TECS_CLMB_MAX"] * G, -v["TECS_SINK_MIN"] * G
    k_thr2ste = (stedot_max - stedot_min) / 1.0
    nom_thr = v["TRIM_THROTTLE"] / 100.0
    tconst = v["TECS_LAND_TCONST"]
    pitch_min_app, pitch_max_app = math.radians(v["PTCH_LIM_MIN_DEG"]), math.radians(v["PTCH_LIM_MAX_DEG"])
    # states
    integ_thr = t0.throttle - nom_thr
    integ_seb = v_app * G * (t0.alpha_rad + gamma)
    last_pitch_dem = t0.alpha_rad + gamma
    stedot_err_last = 0.0
    flaring = False
    flare = {}
    defl = {"elevator_rad": t0.elevator_rad, "aileron_rad": t0.aileron_rad}
    rate_i = {"elevator_rad": out_of("elevator_rad", t0.elevator_rad), "aileron_rad": out_of("aileron_rad",
                                                                                           t0.aileron_rad)}
    throttle = t0.throttle
    prev_tas = v_app
    result = Landing()
    try:
        s = host.get(names)
        for k in range(round(max_s / dt)):
            t = k * dt
            h, climb, tas = s["altitude_m"], -s["vel_down_m_s"], s["airspeed_m_s"]
            vel_dot = (tas - prev_tas) / dt
            prev_tas = tas
            north = s["pos_north_m"]
            # --- AP_Landing: the flare trigger (height or vertical time to touchdown)
            if not flaring and (h <= v["LAND_FLARE_ALT"] or (climb < 0 and h <= -climb * v["LAND_FLARE_SEC"])):
                flaring = True
                flare = {"h0": h, "climb0": climb, "hdem": h, "ideal": h}
                result.flare_height_m = h
            # --- AP_TECS height and speed demands
            if not flaring:
                proportion = min(max(north / x_land, 0.0), 1.0)
                hgt_rate_dem = -v_app * math.tan(-gamma)
                hgt_dem = (x_land - north) * math.tan(-gamma)
                ske_w = 1.0 * (1.0 - proportion)  # TECS_LAND_SPDWGT -1: sliding from TECS_SPDWEIGHT 1 to 0
                p_min, p_max = pitch_min_app, pitch_max_app
                pitch_damp = v["TECS_PTCH_DAMP"]
            else:
                holdoff = v["TECS_FLARE_HGT"]
                frac = (min(max((flare["h0"] - h) / (flare["h0"] - holdoff), 0.0), 1.0)
                        if flare["h0"] > holdoff else 1.0)
                hgt_rate_dem = flare["climb0"] * (1.0 - frac) - v["TECS_LAND_SINK"] * frac
                flare["hdem"] += dt * hgt_rate_dem
                flare["ideal"] += dt * hgt_rate_dem
                hgt_dem = flare["hdem"] * (1.0 - frac) + flare["ideal"] * frac
                ske_w = 0.0
                p_min = math.radians(v["LAND_PITCH_DEG"])
                p_max = math.radians(v["TECS_LAND_PMAX"]) if v["TECS_LAND_PMAX"] else pitch_max_app
                pitch_damp = v["TECS_LAND_DAMP"]
            spe_w = min(2.0 - ske_w, 1.0)
            ske_w = min(ske_w, 1.0)
            spe_dem, ske_dem = hgt_dem * G, 0.5 * v_app * v_app
            spe_est, ske_est = h * G, 0.5 * tas * tas
            spedot, skedot = climb * G, tas * vel_dot
            # --- throttle (with airspeed): zero in the flare (the motor stopped)
            if flaring:
                throttle_dem = 0.0
            else:
                spedot_dem = (spe_dem - spe_est) / tconst
                ste_err = spe_dem - spe_est + ske_dem - ske_est
                stedot_dem = min(max(spedot_dem, stedot_min), stedot_max)
                stedot_err = stedot_dem - spedot - skedot
                stedot_err = 2.0 * dt * stedot_err + (1.0 - 2.0 * dt) * stedot_err_last
                stedot_err_last = stedot_err
                k_ste2thr = 1.0 / (tconst * k_thr2ste)
                ff = nom_thr + stedot_dem / k_thr2ste
                throttle_dem = (ste_err + stedot_err * v["TECS_THR_DAMP"]) * k_ste2thr + ff
                integ_thr += ste_err * v["TECS_INTEG_GAIN"] * dt * k_ste2thr
                integ_thr = min(max(integ_thr, -0.5), 0.5)
                throttle_dem = min(max(throttle_dem + integ_thr, 0.0), 1.0)
            # --- pitch
            seb_err = (spe_dem * spe_w - ske_dem * ske_w) - (spe_est * spe_w - ske_est * ske_w)
            sebdot_dem = hgt_rate_dem * G * spe_w + seb_err / tconst
            sebdot_dem = min(max(sebdot_dem, -v["TECS_SINK_MAX"] * G), v["TECS_CLMB_MAX"] * G)
            sebdot_err = sebdot_dem - (spedot * spe_w - skedot * ske_w)
            sebdot_total = sebdot_dem + sebdot_err * pitch_damp
            gain_inv = tas * G
            lo_i = gain_inv * (p_min - math.radians(5)) - sebdot_total
            hi_i = gain_inv * (p_max + math.radians(5)) - sebdot_total
            delta = sebdot_err * v["TECS_INTEG_GAIN"] * dt
            unc = (sebdot_total + integ_seb + delta) / gain_inv
            if not ((unc > p_max and delta > 0) or (unc < p_min and delta < 0)):
                integ_seb += delta
            integ_seb = min(max(integ_seb, lo_i), hi_i)
            pitch_dem = (sebdot_total + integ_seb) / gain_inv
            step = dt * v["TECS_VERT_ACC"] / tas
            pitch_dem = min(max(pitch_dem, last_pitch_dem - step), last_pitch_dem + step)
            pitch_dem = min(max(pitch_dem, p_min), p_max)
            last_pitch_dem = pitch_dem
            # --- attitude -> rate -> surface (AP_PitchController / AP_RollController, speed scaler)
            scaler = v["SCALING_SPEED"] / max(tas, 1.0)
            inputs = {"throttle": throttle_dem, "rudder_rad": 0.0}
            for name, prefix, angle, rate, demand, tc in (
                    ("elevator_rad", "PTCH", s["pitch_rad"], s["rate_body_y_rad_s"], pitch_dem,
                     v["PTCH2SRV_TCONST"]),
                    ("aileron_rad", "RLL", s["roll_rad"], s["rate_body_x_rad_s"], 0.0, v["RLL2SRV_TCONST"])):
                rate_dem = (demand - angle) * DEG / tc
                err = rate_dem - rate * DEG
                rate_i[name] = min(max(rate_i[name] + v[f"{prefix}_RATE_I"] * err * scaler * scaler * dt,
                                       -0.666 * DEG), 0.666 * DEG)
                out = (v[f"{prefix}_RATE_FF"] * rate_dem * scaler + v[f"{prefix}_RATE_P"] * err * scaler * scaler
                       + rate_i[name])
                command = surface(name, out)
                defl[name] += (command - defl[name]) * (1.0 - math.exp(-dt / SERVO_TAU_S))
                inputs[name] = defl[name]
            throttle += (throttle_dem - throttle) * (1.0 - math.exp(-dt / SERVO_TAU_S))
            inputs["throttle"] = throttle
            result.rows.append((t, north, h, climb, tas, math.degrees(s["pitch_rad"]), throttle, float(flaring)))
            host.step(t, dt, inputs)
            before, s = s, host.get(names)
            if bool(host.slave.getBoolean(on_ground_vr)[0]):  # the gear touched during this step: its start state
                result.touchdown_sink_m_s = before["vel_down_m_s"]
                result.touchdown_airspeed_m_s = before["airspeed_m_s"]
                result.touchdown_north_m = before["pos_north_m"] - x_land
                break
    finally:
        host.close()
    return result
