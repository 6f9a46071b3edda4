"""The tables of each study, in the paper's layout: which cell metrics are columns, which cell fields
label the rows, and the headers."""

from __future__ import annotations

from dataclasses import dataclass

from ..envs.maneuvers import MANEUVERS
from ..evaluation.ground_effect_trim import H_OVER_B
from ..evaluation.robustness import FAMILIES
from ..transforms.presets import GRID
from .results import Column

#: The sea states of the sea-state study's tables (its scales fly these).
SEA_STATES: tuple[int, ...] = (0, 1, 2, 3, 4, 5)

#: The landing study's arms: (summary prefix, header label).
LANDING_ARMS: tuple[tuple[str, str], ...] = (("ge", "GE"), ("no_ge", "no GE"))
#: The landing study's touchdown columns: (metric, header, digits).
LANDING_TOUCHDOWN: tuple[tuple[str, str, int], ...] = (
    ("landed_within_limits", "In limits", 2), ("sink_rate_mps", "Sink", 2), ("pitch_deg", "Pitch", 1))

_TITLES = {"circle": "Circle", "figure8": "Fig.-8", "helix": "Helix", "s_turn": "S-turn"}


@dataclass(frozen=True)
class StudyTable:
    """One table: ``name`` (file label), ``title`` (caption), row ``labels`` (cell fields or params)
    with their ``headers``, and metric ``columns``."""

    name: str
    title: str
    labels: tuple[str, ...]
    headers: tuple[str, ...]
    columns: tuple[Column, ...]


STUDY_TABLES: dict[str, tuple[StudyTable, ...]] = {
    "altitude": (StudyTable(
        "protocol", "Altitude acquisition and hold", ("airframe", "controller"), ("Airframe", "Alg."),
        (Column("survival", "Surv."), Column("acquisition", "Acq."), Column("rmse_m", "RMSE (m)"),
         Column("settling_time_s", "t_s (s)", 1), Column("overshoot_m", "Over. (m)"))),),
    "maneuvers": (
        StudyTable("bank", "Bank-angle RMSE (deg), mean +- std over seeds", ("airframe", "controller"),
                   ("Airframe", "Alg."),
                   tuple(Column(f"{m}/bank_rmse_deg", _TITLES[m]) for m in MANEUVERS)),
        StudyTable("band", "Bank time-in-band (fraction within +-8.6 deg)", ("airframe", "controller"),
                   ("Airframe", "Alg."),
                   tuple(Column(f"{m}/bank_time_in_band", _TITLES[m]) for m in MANEUVERS)),
        StudyTable("channels", "Climb-rate and airspeed RMSE (m/s) over the four maneuvers",
                   ("airframe", "controller"), ("Airframe", "Alg."),
                   tuple(Column(f"{m}/{k}", f"{_TITLES[m]} {u}") for m in MANEUVERS
                         for k, u in (("climb_rate_rmse_mps", "hdot"), ("airspeed_rmse_mps", "V"))))),
    "ground-effect": (
        StudyTable("policy", "Ground-effect impact on thrust: Delta T_pi (%), the thrust change while the "
                   "controller holds each h/b band, correction on vs off", ("airframe", "controller"),
                   ("Airframe", "Alg."),
                   tuple(Column(f"{b:g}/delta_t_pi_pct", f"h/b {b:g}") for b in H_OVER_B)),
        StudyTable("trim", "Delta T (%) of the trim-only table and the lifting-line theory at the same bands",
                   ("airframe", "controller"), ("Airframe", "Alg."),
                   tuple(Column(f"{b:g}/{k}", f"{b:g} {u}") for b in H_OVER_B
                         for k, u in (("delta_t_trim_pct", "trim"), ("theory_pct", "theory"))))),
    "robustness": tuple(StudyTable(
        f"{family}-{metric}", f"Attitude-executor robustness, {family}: {title} (true state)",
        ("airframe", "controller"), ("Airframe", "Alg."),
        tuple(Column(f"{family}/{level}/{metric}", level) for level in GRID))
        for family in FAMILIES
        for metric, title in (("survival", "survival"), ("bank_rmse_deg", "bank RMSE (deg)"))),
    "sea-state": tuple(StudyTable(
        name, f"Sea skimming at 0.25 b over sea states 0-5: {title}", ("airframe", "controller"),
        ("Airframe", "Alg."), tuple(Column(f"{code}/{metric}", f"SS{code}", digits) for code in SEA_STATES))
        for name, metric, title, digits in (
            ("contacts", "water_contact_rate", "water-contact rate", 2),
            ("rmse", "clearance_rmse_span", "clearance RMSE (spans, surviving episodes)", 3),
            ("power", "power_saved", "power saved against free flight (fraction, surviving episodes)", 3))),
    "landing": (
        StudyTable("touchdown", "Landing: touchdowns within the limits, the touchdown's sink rate (m/s) and "
                   "pitch (deg), ground effect on / off", ("airframe", "controller"), ("Airframe", "Alg."),
                   tuple(Column(f"{arm}/{metric}", f"{title} {label}", digits)
                         for metric, title, digits in LANDING_TOUCHDOWN for arm, label in LANDING_ARMS)),
        StudyTable("float", "Landing: where the wheels touched (m past the aim point) and the float from "
                   "ground effect's band (m), ground effect on / off", ("airframe", "controller"),
                   ("Airframe", "Alg."),
                   tuple(Column(f"{arm}/{metric}", f"{title} {label}", 1)
                         for metric, title in (("longitudinal_m", "Long."), ("float_m", "Float"))
                         for arm, label in LANDING_ARMS))),
}
