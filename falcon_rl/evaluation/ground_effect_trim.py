"""Ground effect and thrust demand by trim: the paper's table of T_GE against T_noGE vs h/b.

For each h/b the airframe is trimmed straight and level at cruise speed with the correction on
and off. The theory column is the lifting-line prediction at fixed lift coefficient: only the
induced drag changes, by the Phillips-Hunsaker factor kappa_D at the out-of-ground-effect trim C_L,
so delta_T / T = (kappa_D - 1) C_Di / C_D, with kappa_D at the height of the wing quarter chord
(where the model applies the correction; rows are labelled by the CG's h/b).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch

from ..airframe import Airframe
from ..physics.dynamics import evaluate
from ..physics.ground_effect import phillips_hunsaker
from ..physics.params import build_params
from ..physics.trim import trim_level

H_OVER_B = (0.25, 0.5, 1.0, 2.0, 3.0, 6.0)


@dataclass
class GroundEffectRow:
    h_over_b: float  # CG height over span (the table's row)
    height_m: float
    wing_h_over_b: float  # wing quarter-chord height over span, where the correction is evaluated
    thrust_ge_n: float
    thrust_no_ge_n: float
    delta_percent: float
    theory_percent: float
    alpha_ge_deg: float
    alpha_no_ge_deg: float
    cl_oge: float
    cd_oge: float
    cdi_oge: float
    kappa_drag: float


def ground_effect_table(airframe: Airframe, airspeed: float | None = None,
                        h_over_b: tuple[float, ...] = H_OVER_B, model: str = "induced"
                        ) -> list[GroundEffectRow]:
    """Rows of the ground-effect thrust table at ``airspeed`` (default: cruise)."""
    v = airframe.envelope.cruise_speed if airspeed is None else airspeed
    ratios = torch.tensor(h_over_b, dtype=torch.float64)
    heights = ratios * airframe.geometry.span
    ge = trim_level(airframe, v, heights, ground_effect=model)
    oge = trim_level(airframe, v, heights, ground_effect=False)
    g = airframe.geometry
    # The model evaluates ground effect at the wing quarter chord (attitude included), so the
    # prediction does too: h_wing / b at the out-of-ground-effect trim.
    params = build_params(airframe, len(h_over_b), dtype=torch.float64, ground_effect=False)
    wing_ratio = evaluate(oge.state, params).wing_height / g.span
    kappa_l, kappa_d = phillips_hunsaker(wing_ratio, torch.tensor(g.aspect_ratio, dtype=torch.float64),
                                         torch.tensor(g.taper_ratio, dtype=torch.float64),
                                         oge.lift_coefficient)
    del kappa_l
    theory = (kappa_d - 1.0) * oge.induced_drag_coefficient / oge.drag_coefficient
    rows = []
    for i, r in enumerate(h_over_b):
        rows.append(GroundEffectRow(
            h_over_b=float(r), height_m=float(heights[i]), wing_h_over_b=float(wing_ratio[i]),
            thrust_ge_n=float(ge.thrust[i]), thrust_no_ge_n=float(oge.thrust[i]),
            delta_percent=float(100 * (ge.thrust[i] / oge.thrust[i] - 1)),
            theory_percent=float(100 * theory[i]),
            alpha_ge_deg=float(torch.rad2deg(ge.alpha[i])),
            alpha_no_ge_deg=float(torch.rad2deg(oge.alpha[i])),
            cl_oge=float(oge.lift_coefficient[i]), cd_oge=float(oge.drag_coefficient[i]),
            cdi_oge=float(oge.induced_drag_coefficient[i]), kappa_drag=float(kappa_d[i]),
        ))
    return rows


def format_table(name: str, rows: list[GroundEffectRow]) -> str:
    """Markdown table in the paper's layout (plus the OGE coefficients used by the theory)."""
    lines = [
        f"### {name}",
        "",
        "| h/b | h (m) | T_GE (N) | T_noGE (N) | dT | Theory | C_L OGE | C_D OGE | C_Di OGE |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r.h_over_b:.2f} | {r.height_m:.2f} | {r.thrust_ge_n:.4g} | {r.thrust_no_ge_n:.4g} | "
            f"{r.delta_percent:+.1f}% | {r.theory_percent:+.1f}% | {r.cl_oge:.3f} | {r.cd_oge:.4f} | "
            f"{r.cdi_oge:.4f} |")
    return "\n".join(lines)


def rows_as_dicts(rows: list[GroundEffectRow]) -> list[dict]:
    return [asdict(r) for r in rows]
