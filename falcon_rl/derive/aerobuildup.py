"""AeroSandbox model of a geometry source, evaluated in falcon-rl's conventions.

Each wing is cut into spanwise strips (``panels`` per side plus the control-surface edges) so that
rate-induced velocities are resolved along the span; AeroBuildup (NeuralFoil sections, Jorgensen
fuselage) gives forces and moments about the CG. AeroBuildup treats components in isolation, so
the horizontal tail is evaluated separately at the downwashed angle of attack
alpha_t = alpha - eps, eps = 2 C_L,wing / (pi A_wing) (lifting-line far field, Nelson eq. 2.24 in
derivative form), with its forces scaled by the tail dynamic-pressure ratio eta_t.

Outputs follow falcon-rl (see ``falcon_rl/physics/aero.py``): C_L, C_D in stability axes, C_Y and
the moments in body FRD axes about the CG; positive elevator = trailing edge down, positive
aileron = right wing down, positive rudder = nose left. AeroSandbox's control deflections are
trailing-edge-down on the listed (right or upper) side, so aileron and rudder change sign here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from .geometry import GeometrySpec, Wing

#: falcon-rl surface sign -> AeroSandbox deflection sign (see the module docstring).
ASB_SIGN = {"elevator": 1.0, "aileron": -1.0, "rudder": -1.0}


def _asb():
    try:
        import aerosandbox as asb
    except ImportError as exc:  # pragma: no cover - exercised only without the extra
        raise ImportError("falcon-rl airframe derive needs AeroSandbox: pip install 'falcon-rl[derive]'"
                          ) from exc
    return asb


@cache
def _airfoil(name: str):
    return _asb().Airfoil(name)


def _stations(wing: Wing) -> tuple[np.ndarray, np.ndarray]:
    """Spanwise stations eta in [0, 1] (strips + surface edges + given sections) and the
    cumulative eta of the given sections."""
    axis = 2 if wing.role == "vertical_tail" else 1
    pos = np.array([s.xyz_le[axis] for s in wing.sections])
    cum = np.abs(pos - pos[0])
    given = cum / cum[-1]
    edges = [e for c in wing.control_surfaces for e in c.span_fraction]
    eta = np.unique(np.round(np.concatenate([np.linspace(0.0, 1.0, wing.panels + 1), given, edges]), 9))
    return eta, given


def build_wing(wing: Wing, deflections_deg: dict[str, float]):
    """AeroSandbox Wing with interpolated strips and deflected control surfaces."""
    asb = _asb()
    eta, given = _stations(wing)
    le = np.array([s.xyz_le for s in wing.sections])
    chord = np.array([s.chord for s in wing.sections])
    twist = np.array([s.twist_deg for s in wing.sections])
    xsecs = []
    for i, e in enumerate(eta):
        k = min(int(np.searchsorted(given, e, side="right")) - 1, len(given) - 2)
        controls = []
        if i + 1 < len(eta):
            mid = 0.5 * (e + eta[i + 1])
            for c in wing.control_surfaces:
                if c.span_fraction[0] <= mid <= c.span_fraction[1]:
                    controls.append(asb.ControlSurface(
                        name=c.kind, symmetric=c.kind == "elevator",
                        deflection=ASB_SIGN[c.kind] * deflections_deg.get(c.kind, 0.0),
                        hinge_point=c.hinge_chord_fraction))
        nearest = wing.sections[k if e - given[k] <= given[k + 1] - e else k + 1]
        xsecs.append(asb.WingXSec(
            xyz_le=[float(np.interp(e, given, le[:, j])) for j in range(3)],
            chord=float(np.interp(e, given, chord)), twist=float(np.interp(e, given, twist)),
            airfoil=_airfoil(nearest.airfoil), control_surfaces=controls))
    return asb.Wing(name=wing.name, symmetric=wing.symmetric, xsecs=xsecs)


def build_fuselages(spec: GeometrySpec) -> list:
    asb = _asb()
    return [asb.Fuselage(name=f.name, xsecs=[
        asb.FuselageXSec(xyz_c=[s.x, 0.0, s.z], width=s.width, height=s.height, shape=2.0)
        for s in f.stations]) for f in spec.fuselages]


@dataclass(frozen=True)
class Reference:
    """Reference geometry of the derived airframe (main wing)."""

    area: float
    span: float
    chord: float  # mean aerodynamic chord
    aspect_ratio: float
    taper_ratio: float
    quarter_chord: tuple[float, float, float]  # MAC quarter chord, body FRD relative to the CG


def reference(spec: GeometrySpec) -> Reference:
    """S, b, MAC, A, taper and the MAC quarter-chord point of the main wing."""
    w = spec.main_wing
    asb_wing = build_wing(w, {})
    area, span = w.area, w.span
    qc = asb_wing.aerodynamic_center()  # geometry axes: MAC quarter chord on the centreline
    cg = spec.cg
    return Reference(
        area=area, span=span, chord=float(asb_wing.mean_aerodynamic_chord()),
        aspect_ratio=span**2 / area, taper_ratio=w.sections[-1].chord / w.sections[0].chord,
        quarter_chord=(-(float(qc[0]) - cg[0]), 0.0, -(float(qc[2]) - cg[2])))


def lift_slope_ratio(wing) -> float:
    """C_L_alpha / c_l_alpha of an AeroSandbox wing, as AeroBuildup models it (AR_3D_factor)."""
    aerolib = _asb().library.aerodynamics
    aspect = float(wing.span()) ** 2 / float(wing.area())
    return float(aerolib.CL_over_Cl(aspect_ratio=aspect, mach=0.0, sweep=float(wing.mean_sweep_angle()),
                                    Cl_is_compressible=True))


def sidewash_factor(spec: GeometrySpec, ref: Reference) -> float:
    """(1 + d sigma / d beta) eta_v of Nelson eq. 2.79 (DATCOM): fin sidewash and dynamic pressure.

    0.724 + 3.06 (S_v/S) / (1 + cos Lambda) + 0.4 z_w / d + 0.009 A, with z_w the distance of the
    wing root below the fuselage centreline and d the maximum fuselage depth (0 without fuselage).
    """
    fins = [w for w in spec.wings if w.role == "vertical_tail"]
    s_v = sum(w.area for w in fins)
    main = spec.main_wing
    root = main.sections[0]
    tip = main.sections[-1]
    sweep = math.atan2((tip.xyz_le[0] + 0.25 * tip.chord) - (root.xyz_le[0] + 0.25 * root.chord),
                       abs(tip.xyz_le[1] - root.xyz_le[1]))
    zw_over_d = 0.0
    if spec.fuselages:
        st = spec.fuselages[0].stations
        xs = [p.x for p in st]
        z_axis = float(np.interp(root.xyz_le[0] + 0.25 * root.chord, xs, [p.z for p in st]))
        zw_over_d = (z_axis - root.xyz_le[2]) / max(p.height for p in st)
    return 0.724 + 3.06 * s_v / ref.area / (1.0 + math.cos(sweep)) + 0.4 * zw_over_d \
        + 0.009 * ref.aspect_ratio


class AeroModel:
    """Evaluates the airframe's coefficients with AeroBuildup at vectorised conditions.

    Corrections to AeroBuildup's isolated-component buildup (each a textbook estimate):
    - downwash at the horizontal tail, eps = 2 C_L,wing / (pi A), tail forces times eta_t;
    - sidewash at the fin, beta_v = k beta with k = (1 + d sigma/d beta) eta_v (Nelson eq. 2.79);
    - control increments times the carrying wing's C_L_alpha / c_l_alpha: AeroBuildup applies its
      finite-wing lift-slope reduction to the section angle of attack but not to the flap
      increment, which otherwise keeps its 2D value (DATCOM scales it by the same ratio).
    """

    def __init__(self, spec: GeometrySpec):
        self.spec = spec
        self.ref = reference(spec)
        self.sidewash = sidewash_factor(spec, self.ref)
        self.control_factor = {}
        for w in spec.wings:
            ratio = lift_slope_ratio(build_wing(w, {}))
            for c in w.control_surfaces:
                self.control_factor[c.kind] = ratio / ratio**0.2  # AeroBuildup keeps ratio**0.2

    def _airplanes(self, deflections_deg: dict[str, float]):
        asb = _asb()
        kw = dict(xyz_ref=list(self.spec.cg), s_ref=self.ref.area, c_ref=self.ref.chord, b_ref=self.ref.span)
        groups = {}
        for role in ("main", "horizontal_tail", "vertical_tail"):
            wings = [build_wing(w, deflections_deg) for w in self.spec.wings if w.role == role]
            fuselages = build_fuselages(self.spec) if role == "main" else []
            groups[role] = asb.Airplane(wings=wings, fuselages=fuselages, **kw)
        return groups

    def coefficients(self, alpha: np.ndarray, beta: np.ndarray, rates_hat: np.ndarray,
                     deflections: tuple[float, float, float]) -> np.ndarray:
        """Coefficients [N, 6] (C_L, C_D, C_Y, C_l, C_m, C_n).

        Args:
            alpha, beta: [N] rad. rates_hat: [N, 3] (p b/2V, q c/2V, r b/2V).
            deflections: (elevator, aileron, rudder) in rad, shared by the N points.
        """
        base = self._raw(alpha, beta, rates_hat, {})
        out = base.copy()
        for kind, d in zip(("elevator", "aileron", "rudder"), deflections, strict=True):
            if d != 0.0:
                moved = self._raw(alpha, beta, rates_hat, {kind: math.degrees(d)})
                out += self.control_factor[kind] * (moved - base)
        return out

    def _raw(self, alpha: np.ndarray, beta: np.ndarray, rates_hat: np.ndarray,
             deflections_deg: dict[str, float]) -> np.ndarray:
        asb = _asb()
        spec, ref = self.spec, self.ref
        v = spec.airspeed
        groups = self._airplanes(deflections_deg)
        rates = dict(p=rates_hat[:, 0] * 2 * v / ref.span, q=rates_hat[:, 1] * 2 * v / ref.chord,
                     r=rates_hat[:, 2] * 2 * v / ref.span)
        atmosphere = asb.Atmosphere(altitude=spec.altitude)

        def op(a, b):
            return asb.OperatingPoint(atmosphere=atmosphere, velocity=v, alpha=np.degrees(a),
                                      beta=np.degrees(b), **rates)

        op0 = op(alpha, beta)
        res = asb.AeroBuildup(groups["main"], op0).run()
        qs = float(op0.dynamic_pressure()) * ref.area
        f_g = [np.asarray(f, dtype=float) for f in res["F_g"]]
        m_g = [np.asarray(m, dtype=float) for m in res["M_g"]]
        _, _, wind_z = op0.convert_axes(*res["wing_aero_components"][0].F_g, from_axes="geometry",
                                        to_axes="wind")
        eps = -2.0 * np.asarray(wind_z) / qs / (math.pi * ref.aspect_ratio)  # lift = -F_w,z
        for role, o, scale in (("horizontal_tail", op(alpha - eps, beta), spec.tail_q_ratio),
                               ("vertical_tail", op(alpha, beta * self.sidewash), 1.0)):
            ab = asb.AeroBuildup(groups[role], o)
            for wing in groups[role].wings:
                comp = ab.wing_aerodynamics(wing, include_induced_drag=True)
                for i in range(3):
                    f_g[i] = f_g[i] + scale * np.asarray(comp.F_g[i])
                    m_g[i] = m_g[i] + scale * np.asarray(comp.M_g[i])
        # geometry axes (x aft, y right, z up) -> body FRD
        cx, cy, cz = -f_g[0] / qs, f_g[1] / qs, -f_g[2] / qs
        cl_roll, cm, cn = -m_g[0] / (qs * ref.span), m_g[1] / (qs * ref.chord), -m_g[2] / (qs * ref.span)
        ca, sa = np.cos(alpha), np.sin(alpha)
        lift_c = cx * sa - cz * ca
        drag_c = -cx * ca - cz * sa
        out = np.stack(np.broadcast_arrays(lift_c, drag_c, cy, cl_roll, cm, cn), axis=-1)
        return out.reshape(len(alpha), 6)
