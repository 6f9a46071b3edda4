"""Guidance laws above an attitude executor, batched over envs (torch): PX4's NPFG and ArduPilot's L1 for the
lateral path, PX4's TECS for height and airspeed, and the path geometry they read. Parameters carry the
autopilots' names, units and defaults."""

from .l1 import L1Output, L1Params, l1_loiter, l1_waypoints
from .npfg import NPFGOutput, NPFGParams, bank_for, npfg
from .paths import PathFrame, circle_frame, line_frame, segment_frame
from .tecs import TECSOutput, TECSParams, TECSState, climb_rate_setpoint, speed_rate_setpoint, tecs_update

__all__ = ["L1Output", "L1Params", "NPFGOutput", "NPFGParams", "PathFrame", "TECSOutput", "TECSParams",
           "TECSState", "bank_for", "circle_frame", "climb_rate_setpoint", "l1_loiter", "l1_waypoints",
           "line_frame", "npfg", "segment_frame", "speed_rate_setpoint", "tecs_update"]
