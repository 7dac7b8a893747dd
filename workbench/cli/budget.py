"""``workbench budget``: error budgets of facilities a calibrated unit is meant for.

``workbench budget reference-facility (--set SET | --grade NAME)``: the covariance analysis of
paper 003's GPS-aided reference facility (:mod:`workbench.nav.reference_facility`) with the
unit's noise (its calibration set's noise block, or a grade), for the flights of table 3, and
the multi-antenna attitude budget (eq. 9-10, Fig. 4). It ends with whether the unit is good
enough for the facility: cm-level position (below a decimetre) and attitude within 0.15° (1-sigma,
every axis; paper 003 sec. 1, :class:`workbench.nav.reference_facility.Requirement`), each better than
the aiding alone (sec. 4).
"""

from __future__ import annotations

from dataclasses import replace

import typer
from rich.table import Table

from workbench.cli import out, styled
from workbench.errors import AnalysisError

budget_app = typer.Typer(no_args_is_help=True, help="Error budgets: is this unit good enough for that facility?")
FIG4_BASELINES_M = (0.5, 1.0, 1.5, 2.0, 3.0)
FIG4_ERRORS_MM = ((2.5, 5.0), (5.0, 10.0))  # (horizontal, vertical) per NED baseline component, paper 003 sec. 3.2
FIG4_ATTITUDE_DEG = (1.0, 5.0, 45.0)  # roll, pitch, heading of Fig. 4
DURATION_RANGE_S = (10.0, 86400.0)  # a flight of the facility: seconds to a day (the 100 Hz covariance
# propagation takes about 1 s of CPU per 300 s of flight; 1e12 s ran for ever)


def _fmt3(values, unit: str, digits: int) -> str:
    import numpy as np

    from workbench.units import to_unit

    return " ".join(f"{v:.{digits}f}" for v in to_unit(np.asarray(values), unit))


@budget_app.command("reference-facility")
def reference_facility(
        set_ref: str = typer.Option(None, "--set", help="Calibration set (id, prefix or JSON file): its noise block."),
        grade: str = typer.Option(None, "--grade", help="A grade (fixtures/units) instead of a set."),
        scenario: str = typer.Option("both", "--scenario", help="straight, loiter or both (paper 003 table 3)."),
        duration_s: float = typer.Option(300.0, "--duration-s", help="Flight time, s."),
        ppr_cm: float = typer.Option(3.0, "--ppr-cm", help="Debiased pseudorange 1-sigma, cm (table 2)."),
        tilt_deg: float = typer.Option(0.3, "--tilt-deg", help="Multi-antenna tilt 1-sigma, ° (table 2)."),
        yaw_deg: float = typer.Option(0.15, "--yaw-deg", help="Multi-antenna yaw 1-sigma, ° (table 2)."),
        pdop: float = typer.Option(4.0, "--pdop", help="Position dilution of precision."),
        vdop: float = typer.Option(3.8, "--vdop", help="Vertical dilution of precision."),
        position_req_cm: float = typer.Option(10.0, "--position-req-cm",
                                              help="Required position 1-sigma, cm (paper 003's cm-level: below a "
                                                   "decimetre)."),
        attitude_req_deg: float = typer.Option(0.15, "--attitude-req-deg", help="Required attitude 1-sigma, °."),
) -> None:
    """Covariance analysis of paper 003's reference facility with this unit, and the verdict."""
    import numpy as np

    from workbench.nav import reference_facility as rf
    from workbench.units import from_unit, label, to_unit

    if (set_ref is None) == (grade is None):
        raise AnalysisError("budget reference-facility: give exactly one of --set and --grade")
    names = list(rf.SCENARIOS) if scenario == "both" else [scenario]
    if any(n not in rf.SCENARIOS for n in names):
        raise AnalysisError(f"--scenario {scenario}: unknown (known: {', '.join(rf.SCENARIOS)}, both)")
    lo, hi = DURATION_RANGE_S
    if not lo <= duration_s <= hi:
        raise AnalysisError(f"--duration-s {duration_s:g}: expected {lo:g} to {hi:g} s")
    for option, value in (("--ppr-cm", ppr_cm), ("--tilt-deg", tilt_deg), ("--yaw-deg", yaw_deg), ("--pdop", pdop),
                          ("--vdop", vdop), ("--position-req-cm", position_req_cm),
                          ("--attitude-req-deg", attitude_req_deg)):
        if not 0.0 < value < float("inf"):  # a sigma, a dilution or a requirement: NaN, 0 and negatives mean nothing
            raise AnalysisError(f"{option} {value:g}: expected a positive finite number")
    if set_ref is not None:
        from workbench.cli.sets import load_set_ref

        imu = rf.ImuErrors.from_set(load_set_ref(set_ref))
    else:
        from workbench.grades import load_spec

        imu = rf.ImuErrors.from_spec(load_spec(grade))
    aiding = rf.Aiding(ppr_sigma_m=from_unit(ppr_cm, "cm"), tilt_sigma=from_unit(tilt_deg, "deg"),
                       yaw_sigma=from_unit(yaw_deg, "deg"), pdop=pdop, vdop=vdop)
    req = rf.Requirement(from_unit(position_req_cm, "cm"), from_unit(attitude_req_deg, "deg"))
    out.print(styled(imu.source, "bold", f": ARW {_fmt3(imu.gyro_white, 'deg/sqrt(h)', 3)} {label('deg/sqrt(h)')}, "
              f"VRW {_fmt3(imu.accel_white, 'm/s/sqrt(h)', 3)} {label('m/s/sqrt(h)')}, gyro bias instability "
              f"{_fmt3(imu.gyro_bias_instability, 'deg/h', 2)} {label('deg/h')}"), highlight=False)
    t = Table("flight", "filter", "within req. (p / att), s", "position N E D, cm", "attitude N E D, °",
              "saw-tooth D, °", title=f"1-sigma peaks over the second half; PPR {ppr_cm:g} cm, PDOP {pdop:g}, "
                                      f"VDOP {vdop:g}, tilt {tilt_deg:g}°, yaw {yaw_deg:g}°")
    verdicts = []
    for name in names:
        scn = replace(rf.SCENARIOS[name], duration_s=duration_s)
        for bias_states in (False, True):
            b = rf.covariance_analysis(imu, scn, aiding, bias_states=bias_states)
            w = b.worst()
            half = len(b.t) // 2
            tooth = float(np.mean(b.sigma_before[half:, 8] - b.sigma_after[half:, 8]))
            conv = " / ".join("never" if c is None else f"{c:.0f}" for c in rf.time_to_requirement(b, req))
            t.add_row(name, "15 (biases)" if bias_states else "9 (eq. 17)", conv,
                      _fmt3(w["position_m"], "cm", 1), _fmt3(w["attitude_rad"], "deg", 3),
                      f"{to_unit(tooth, 'deg'):.4f}")
            if bias_states:
                verdicts.append((name, w, rf.meets(b, req), rf.adds_value(b, aiding)))
    out.print(t)
    a = Table("L, m", *[f"heading / pitch, ° (σh {h:g}, σv {v:g} mm)" for h, v in FIG4_ERRORS_MM],
              title="multi-antenna attitude (paper 003 eq. 9-10, Fig. 4) at roll, pitch, heading "
                    f"{', '.join(f'{x:g}' for x in FIG4_ATTITUDE_DEG)}°")
    rph = from_unit(np.asarray(FIG4_ATTITUDE_DEG), "deg")
    for L in FIG4_BASELINES_M:
        cells = []
        for h, v in FIG4_ERRORS_MM:
            s = to_unit(rf.antenna_attitude_sigma(L, from_unit(h, "mm"), from_unit(v, "mm"), rph), "deg")
            cells.append(f"{s[2]:.3f} / {s[1]:.3f}")
        a.add_row(f"{L:g}", *cells)
    out.print(a)
    fix_p, fix_a = rf.aiding_alone(aiding)
    out.print(f"aiding alone: position fix {_fmt3(fix_p, 'cm', 1)} cm N/E/D, antenna attitude "
              f"{_fmt3(fix_a, 'deg', 2)}° N/E/D", highlight=False)
    for name, w, (pos_ok, att_ok), (pos_gain, att_gain) in verdicts:
        ok = pos_ok and att_ok and pos_gain and att_gain
        out.print(f"{name} (biases as states): position {'met' if pos_ok else 'NOT met'} (peak "
                  f"{to_unit(w['position_m'].max(), 'cm'):.1f} <= {position_req_cm:g} cm"
                  f"{'' if pos_gain else ', height NOT better than the fix alone'}), attitude "
                  f"{'met' if att_ok else 'NOT met'} (peak {to_unit(w['attitude_rad'].max(), 'deg'):.3f} <= "
                  f"{attitude_req_deg:g}°{'' if att_gain else ', NOT better than the antennas alone'})",
                  style="green" if ok else "bold red", highlight=False)
    good = all(p and q and pg and ag for _, _, (p, q), (pg, ag) in verdicts)
    out.print(f"verdict: {imu.source} is {'good enough' if good else 'NOT good enough'} for the reference facility",
              style="bold green" if good else "bold red", highlight=False)


def register(app: typer.Typer) -> None:
    app.add_typer(budget_app, name="budget")
