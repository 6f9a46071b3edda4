"""Export an :class:`~falcon_rl.airframe.Airframe` to a self-contained JSBSim aircraft.

``export_aircraft(airframe, directory)`` writes ``directory/aircraft/<name>/<name>.xml`` that
reproduces the falcon-rl model term by term (JSBSim units: ft, ft^2, slug ft^2, lbs):

- Metrics and mass balance: S, b, c; the CG, the aerodynamic reference point and the visual
  reference point all at the structural origin, so JSBSim adds no r x F moment to the aero
  moments, which are about the CG as in ``physics/aero.py``. Inertia incl. products of inertia
  (sign conventions in :func:`_mass_balance`).
- Aerodynamics as JSBSim functions: the same monomial tables in (alpha, beta, d_e, d_a, d_r),
  alpha and beta clamped to the table range, plus the rate terms in p b/2V, q c/2V, r b/2V with
  V floored at 0.1 m/s. Forces are written in BODY axes (X, Y, Z) from C_L and C_D with the
  alpha rotation of our stability-axis model, F = qS [-CD cos a + CL sin a, CY, -CD sin a - CL cos a].
  JSBSim's DRAG/SIDE/LIFT axes would rotate through beta too (wind axes), which differs from our
  model as soon as beta != 0, hence BODY axes.
- Ground effect: the Phillips-Hunsaker kappa_L, kappa_D with the high-lift corrections at the
  height of the wing quarter chord over the span, computed from ``position/h-agl-ft`` and the
  attitude (not ``aero/h_b-mac-ft``, which is the height of the aerodynamic reference point, here
  the CG). Scaled by the run-time switch ``aero/falcon/ground-effect`` (1 on, 0 off).
- Flight control: ``fcs/{elevator,aileron,rudder}-cmd-norm`` and ``fcs/falcon/throttle-cmd-norm``
  in [-1, 1] are clipped and mapped affinely as in ``physics/actuators.py``; each surface goes
  through a ``second_order_filter`` w_n^2 / (s^2 + 2 zeta w_n s + w_n^2) (a ``lag_filter`` for
  first-order actuators) and is clipped to its limits, into ``fcs/elevator-pos-rad``,
  ``fcs/left-aileron-pos-rad`` (our single antisymmetric aileron) and ``fcs/rudder-pos-rad``;
  each motor's throttle goes through a ``lag_filter`` into ``fcs/falcon/throttle-pos-<m>``.
  JSBSim filters start from zero internal state, so they act on the deviation from the
  properties ``fcs/falcon/<surface>-trim`` / ``fcs/falcon/throttle-<m>-trim`` (set them to the
  initial actuator positions before ``run_ic``): the actuators then start at rest there, like ours.
  The filters are Tustin-discretised with the dt in force when the model is loaded: call
  ``set_dt`` before ``load_model``. Residual: our saturation also zeroes the actuator rate at a
  limit, JSBSim only clips the output.
- Propulsion: no JSBSim engine; each motor is an ``<external_reactions>`` force at the motor
  position along its thrust axis whose magnitude is our momentum-theory thrust of the lagged
  throttle, the air density and the axial airspeed (and a reaction moment when k_tp != 0).
- No contact points: like our simulator, nothing stops the aircraft at the ground plane.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from ..airframe import AERO_COEFFICIENTS, AERO_VARIABLES, Airframe, Motor
from ..constants import FT, LBF, LBM, SLUG_FT2
from .jsbsim_xml import (
    Expr,
    body_to_structural_in,
    clamp,
    function,
    text,
    triplet,
)

MIN_AIRSPEED_FPS = 0.1 / FT  # the floor of physics/aero.py for the non-dimensional rates
H_OVER_B_MIN = 0.05  # clamp of physics/ground_effect.py
GE_SWITCH = "aero/falcon/ground-effect"
THROTTLE_CMD = "fcs/falcon/throttle-cmd-norm"
SURFACE_NAMES = ("elevator", "aileron", "rudder")
SURFACE_CMD = ("fcs/elevator-cmd-norm", "fcs/aileron-cmd-norm", "fcs/rudder-cmd-norm")
SURFACE_POS = ("fcs/elevator-pos-rad", "fcs/left-aileron-pos-rad", "fcs/rudder-pos-rad")
COEFFICIENT = {name: f"aero/falcon/{name}" for name in AERO_COEFFICIENTS}  # after ground effect
KAPPA_L, KAPPA_D = "aero/falcon/kappa-L", "aero/falcon/kappa-D"


def throttle_property(m: int) -> str:
    """Lagged throttle state of motor ``m`` in [0, 1]."""
    return f"fcs/falcon/throttle-pos-{m}"


def export_aircraft(airframe: Airframe, directory: str | Path, ground_effect: str = "induced"
                    ) -> Path:
    """Write the JSBSim aircraft for ``airframe`` under ``directory``; returns the XML path.

    ``directory`` becomes a JSBSim root: load it with ``FGFDMExec(str(directory))`` and
    ``load_model(airframe.name)``. ``ground_effect`` is "induced" (our default: only the
    induced drag is scaled) or "paper" (C_D = C_D_inf kappa_D kappa_L^2); set the property
    ``aero/falcon/ground-effect`` to 0 to fly without ground effect. Only monomial airframes are
    exported: a tabulated one (imported from JSBSim) is compared with its source aircraft instead
    (``jsbsim_model_compare``, ``validate jsbsim --jsbsim-model``).
    """
    if airframe.aero.kind != "monomial":
        raise ValueError(f"{airframe.name}: the JSBSim export writes monomial aero models only; compare an "
                         "imported airframe with its JSBSim aircraft: validate jsbsim --jsbsim-model NAME")
    if ground_effect not in ("induced", "paper"):
        raise ValueError(f"ground_effect must be 'induced' or 'paper', got {ground_effect!r}")
    root = ET.Element("fdm_config", {"name": airframe.name, "version": "2.0", "release": "BETA"})
    header = ET.SubElement(root, "fileheader")
    text(header, "author", "falcon-rl JSBSim exporter")
    text(header, "description", f"{airframe.display_name}: exported from the falcon-rl airframe "
                                f"'{airframe.name}' for cross-simulator validation")
    _metrics(root, airframe)
    _mass_balance(root, airframe)
    ET.SubElement(root, "ground_reactions")
    ET.SubElement(root, "propulsion")
    _flight_control(root, airframe)
    _external_reactions(root, airframe)
    _aerodynamics(root, airframe, ground_effect)
    ET.indent(root)
    path = Path(directory) / "aircraft" / airframe.name / f"{airframe.name}.xml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text('<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n")
    return path


def _metrics(root: ET.Element, airframe: Airframe) -> None:
    g = airframe.geometry
    metrics = ET.SubElement(root, "metrics")
    text(metrics, "wingarea", g.wing_area / FT**2, "FT2")
    text(metrics, "wingspan", g.span / FT, "FT")
    text(metrics, "chord", g.mean_chord / FT, "FT")
    for tag, unit in (("htailarea", "FT2"), ("htailarm", "FT"), ("vtailarea", "FT2"), ("vtailarm", "FT")):
        text(metrics, tag, 0.0, unit)
    for name in ("AERORP", "EYEPOINT", "VRP"):
        triplet(metrics, "location", (0.0, 0.0, 0.0), "IN", name=name)


def _mass_balance(root: ET.Element, airframe: Airframe) -> None:
    """Empty weight and inertia about the CG (at the structural origin).

    JSBSim's XML products of inertia are positive integrals in its structural frame (x aft, y
    right, z up) and enter J negated (its default ``negated_crossproduct_inertia``). Going from
    body FRD to structural axes flips the sign of xy and yz (not xz), so with ours,
    J = [[Ixx, -Ixy, -Ixz], ...] in body axes: ixy_xml = Ixy, iyz_xml = Iyz, ixz_xml = -Ixz.
    """
    j = airframe.inertia / SLUG_FT2
    mass = ET.SubElement(root, "mass_balance")
    for tag, value in (("ixx", j[0, 0]), ("iyy", j[1, 1]), ("izz", j[2, 2]), ("ixy", -j[0, 1]),
                       ("ixz", j[0, 2]), ("iyz", -j[1, 2])):
        text(mass, tag, value, "SLUG*FT2")
    text(mass, "emptywt", airframe.mass / LBM, "LBS")
    triplet(mass, "location", (0.0, 0.0, 0.0), "IN", name="CG")


def _lagged(channel: ET.Element, name: str, target: str, coefs: tuple[float, ...],
            limits: tuple[float, float], output: str) -> None:
    """output = clip(trim + H(s) (target - trim)), H a first- (one coefficient) or second-order
    unit-gain filter; ``trim`` is the property ``<name>-trim`` (set it before ``run_ic``).

    JSBSim filters start from zero internal state, not from their first input, so they filter the
    deviation from the initial (trim) value: they then start exactly at rest, like our actuators.
    """
    trim = f"fcs/falcon/{name}-trim"
    deviation = ET.SubElement(channel, "fcs_function", {"name": f"fcs/falcon/{name}-deviation"})
    function(deviation, None, ("difference", target, trim))
    tag = "lag_filter" if len(coefs) == 1 else "second_order_filter"
    filt = ET.SubElement(channel, tag, {"name": f"fcs/falcon/{name}-filter"})
    text(filt, "input", f"fcs/falcon/{name}-deviation")
    for i, c in enumerate(coefs, start=1):
        text(filt, f"c{i}", c)
    out = ET.SubElement(channel, "fcs_function", {"name": output})
    function(out, None, clamp(("sum", trim, f"fcs/falcon/{name}-filter"), *limits))


def _flight_control(root: ET.Element, airframe: Airframe) -> None:
    fcs = ET.SubElement(root, "flight_control", {"name": "falcon-rl actuators"})
    ET.SubElement(fcs, "property", {"value": "0"}).text = THROTTLE_CMD
    for name in (*SURFACE_NAMES, *(f"throttle-{m}" for m in range(airframe.num_motors))):
        ET.SubElement(fcs, "property", {"value": "0"}).text = f"fcs/falcon/{name}-trim"
    channel = ET.SubElement(fcs, "channel", {"name": "surfaces"})
    for name, cmd, pos in zip(SURFACE_NAMES, SURFACE_CMD, SURFACE_POS, strict=True):
        act = airframe.actuators[name]
        lo, hi = act.limits
        target = f"fcs/falcon/{name}-target-rad"
        comp = ET.SubElement(channel, "fcs_function", {"name": target})
        function(comp, None, ("sum", lo, ("product", 0.5 * (hi - lo), ("sum", clamp(cmd, -1.0, 1.0), 1.0))))
        if act.order == 2:
            wn, zeta = act.natural_frequency, act.damping_ratio
            coefs: tuple[float, ...] = (0.0, 0.0, wn * wn, 1.0, 2.0 * zeta * wn, wn * wn)
        else:
            coefs = (1.0 / act.time_constant,)
        _lagged(channel, name, target, coefs, (lo, hi), pos)
    channel = ET.SubElement(fcs, "channel", {"name": "throttle"})
    target = "fcs/falcon/throttle-target"
    comp = ET.SubElement(channel, "fcs_function", {"name": target})
    function(comp, None, ("product", 0.5, ("sum", clamp(THROTTLE_CMD, -1.0, 1.0), 1.0)))
    for m, motor in enumerate(airframe.motors):
        _lagged(channel, f"throttle-{m}", target, (1.0 / motor.time_constant,), (0.0, 1.0),
                throttle_property(m))


def _thrust_lbs(motor: Motor, m: int) -> Expr:
    """Momentum-theory thrust (lbf) of motor ``m``: 1/2 rho S_p C_p V_d (V_d - V_ax), >= 0."""
    ax, ay, az = motor.thrust_axis
    v_axial = ("sum", ("product", ax, "velocities/u-aero-fps"), ("product", ay, "velocities/v-aero-fps"),
               ("product", az, "velocities/w-aero-fps"))
    delta = throttle_property(m)
    v_d = ("sum", v_axial, ("product", delta, ("difference", motor.discharge_speed / FT, v_axial)))
    k = 0.5 * (motor.disk_area / FT**2) * motor.thrust_coefficient
    return ("max", ("product", k, "atmosphere/rho-slugs_ft3", v_d, ("difference", v_d, v_axial)), 0.0)


def _external_reactions(root: ET.Element, airframe: Airframe) -> None:
    ext = ET.SubElement(root, "external_reactions")
    for m, motor in enumerate(airframe.motors):
        force = ET.SubElement(ext, "force", {"name": f"motor-{m}", "frame": "BODY", "unit": "LBS"})
        function(force, None, _thrust_lbs(motor, m), f"thrust of {motor.name}, lbf")
        triplet(force, "location", body_to_structural_in(motor.position), "IN")
        triplet(force, "direction", motor.thrust_axis)
        if motor.torque_coefficient > 0.0 and motor.torque_speed_constant != 0.0:
            moment = ET.SubElement(ext, "moment", {"name": f"motor-{m}-torque", "frame": "BODY",
                                                   "unit": "LBSFT"})
            k = -motor.spin * motor.torque_coefficient * motor.torque_speed_constant**2 / (LBF * FT)
            delta = throttle_property(m)
            function(moment, None, ("product", k, delta, delta), f"reaction torque of {motor.name}")
            triplet(moment, "direction", motor.thrust_axis)


def _aerodynamics(root: ET.Element, airframe: Airframe, ge_model: str) -> None:
    a = airframe.aero
    aero = ET.SubElement(root, "aerodynamics")
    ET.SubElement(aero, "property", {"value": "1"}).text = GE_SWITCH
    variables = {"alpha": "aero/falcon/alpha", "beta": "aero/falcon/beta", "elevator": SURFACE_POS[0],
                 "aileron": SURFACE_POS[1], "rudder": SURFACE_POS[2]}
    function(aero, variables["alpha"], clamp("aero/alpha-rad", *a.alpha_range), "alpha clamped, rad")
    function(aero, variables["beta"], clamp("aero/beta-rad", *a.beta_range), "beta clamped, rad")
    inv_2v = ("quotient", 0.5, ("max", "velocities/vt-fps", MIN_AIRSPEED_FPS))
    rate_hat = {
        "p": ("product", "velocities/p-aero-rad_sec", "metrics/bw-ft", inv_2v),
        "q": ("product", "velocities/q-aero-rad_sec", "metrics/cbarw-ft", inv_2v),
        "r": ("product", "velocities/r-aero-rad_sec", "metrics/bw-ft", inv_2v),
    }
    for name, node in rate_hat.items():
        function(aero, f"aero/falcon/{name}-hat", node)
    for k, cname in enumerate(AERO_COEFFICIENTS):
        terms: list[Expr] = []
        for t, powers in enumerate(a.exponents):
            coef = float(a.coefficients[t, k])
            if coef != 0.0:
                factors = [variables[v] for v, e in zip(AERO_VARIABLES, powers, strict=True)
                           for _ in range(e)]
                terms.append(("product", coef, *factors) if factors else coef)
        for j, rname in enumerate(("p", "q", "r")):
            coef = float(a.rate_derivatives[k, j])
            if coef != 0.0:
                terms.append(("product", coef, f"aero/falcon/{rname}-hat"))
        function(aero, f"aero/falcon/{cname}-oge", ("sum", 0.0, *terms), f"{cname} out of ground effect")
    _ground_effect(aero, airframe, ge_model)
    qs = ("product", "aero/qbar-psf", "metrics/Sw-sqft")
    ca, sa = ("cos", "aero/alpha-rad"), ("sin", "aero/alpha-rad")
    cl, cd = COEFFICIENT["CL"], COEFFICIENT["CD"]
    axes = {
        "X": ("product", qs, ("difference", ("product", cl, sa), ("product", cd, ca))),
        "Y": ("product", qs, COEFFICIENT["CY"]),
        "Z": ("product", -1.0, qs, ("sum", ("product", cd, sa), ("product", cl, ca))),
        "ROLL": ("product", qs, "metrics/bw-ft", COEFFICIENT["Cl"]),
        "PITCH": ("product", qs, "metrics/cbarw-ft", COEFFICIENT["Cm"]),
        "YAW": ("product", qs, "metrics/bw-ft", COEFFICIENT["Cn"]),
    }
    for axis, node in axes.items():
        el = ET.SubElement(aero, "axis", {"name": axis, "frame": "BODY"} if axis in "XYZ" else {"name": axis})
        function(el, f"aero/falcon/force-{axis.lower()}", node)


def _ground_effect(aero: ET.Element, airframe: Airframe, ge_model: str) -> None:
    """Phillips-Hunsaker factors at the wing quarter chord, and C_L, C_D after ground effect."""
    g, a = airframe.geometry, airframe.aero
    ra, rt = g.aspect_ratio, g.taper_ratio
    qx, qy, qz = (v / FT for v in g.wing_quarter_chord)
    st, ct = ("sin", "attitude/theta-rad"), ("cos", "attitude/theta-rad")
    sp, cp = ("sin", "attitude/phi-rad"), ("cos", "attitude/phi-rad")
    down = ("sum", ("product", -qx, st), ("product", qy, sp, ct), ("product", qz, cp, ct))
    wing_height = ("difference", "position/h-agl-ft", down)
    function(aero, "aero/falcon/wing-height-ft", wing_height, "height of the wing quarter chord, ft")
    x = "aero/falcon/h-b"
    function(aero, x, ("max", ("quotient", "aero/falcon/wing-height-ft", "metrics/bw-ft"), H_OVER_B_MIN),
             "quarter-chord height over span, clamped as in physics/ground_effect.py")
    delta_d = 1.0 - 0.157 * (rt**0.775 - 0.373) * (ra**0.417 - 1.27)
    delta_l = 1.0 - 2.25 * (rt**0.00273 - 0.997) * (ra**0.717 + 13.6)
    cl_abs = ("abs", COEFFICIENT["CL"] + "-oge")

    def decay(scale: float, power: float) -> Expr:  # exp(-scale x^power)
        return ("exp", ("product", -scale, ("pow", x, power)))

    def high_lift(k: float, cl_power: float, x_power: float) -> Expr:  # 1 + k |CL|^a / x^b
        return ("sum", 1.0, ("quotient", ("product", k, ("pow", cl_abs, cl_power)), ("pow", x, x_power)))

    kappa_d = ("product", ("difference", 1.0, ("product", delta_d, decay(4.74, 0.814)),
                           ("product", x, x, decay(3.88, 0.758))),
               high_lift(0.0361 / ra**1.19, 1.21, 1.51))
    kappa_l = ("quotient", ("sum", 1.0, ("product", delta_l * 288.0 / ra**0.882, ("pow", x, 0.787),
                                         decay(9.14, 0.327))),
               high_lift(0.269 / ra**3.18, 1.45, 1.12))
    for name, node in ((KAPPA_L, kappa_l), (KAPPA_D, kappa_d)):
        function(aero, name, ("sum", 1.0, ("product", GE_SWITCH, ("difference", node, 1.0))))
    cl_inf, cd_inf = COEFFICIENT["CL"] + "-oge", COEFFICIENT["CD"] + "-oge"
    function(aero, COEFFICIENT["CL"], ("product", KAPPA_L, cl_inf), "CL in ground effect")
    if ge_model == "induced":
        k = 1.0 / (math.pi * a.oswald_efficiency * ra)
        cl = COEFFICIENT["CL"]
        cd = ("sum", cd_inf, ("product", k, ("difference", ("product", KAPPA_D, cl, cl),
                                             ("product", cl_inf, cl_inf))))
    else:
        cd = ("product", cd_inf, KAPPA_D, KAPPA_L, KAPPA_L)
    function(aero, COEFFICIENT["CD"], cd, "CD in ground effect")
    for cname in AERO_COEFFICIENTS[2:]:
        function(aero, COEFFICIENT[cname], COEFFICIENT[cname] + "-oge")
