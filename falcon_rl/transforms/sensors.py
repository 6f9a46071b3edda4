"""Sensor chain as a TorchRL transform: GPS position and velocity, attitude, gyro rates, airspeed.

Per channel (each component of it), in this order:

    y = (1 + s) x + b + sigma n        scale-factor error s and bias b (fixed + drawn per episode),
                                       white Gaussian noise n ~ N(0, 1) every env step
    y = clip(y, lo, hi)                sensor limits
    y = res round(y / res)             quantisation
    sample every 1 / rate s, zero-order hold in between (the sample clock restarts at each reset)
    release after the transport delay  (per-env ring buffer, refilled on reset)

The attitude channel (quaternion) takes only noise (sigma in rad of rotation, as N(0, (sigma/2)^2)
on each component) and limits, then is renormalised; sampling and delay apply as to the others.

Output: ("measured", ...) holds the state as the sensors report it: the measured channels, the
fields derived from them (height from the GPS position, Euler angles from the attitude, body velocity
from the GPS velocity rotated by the measured attitude), the rest copied from the truth (alpha, beta,
surfaces, throttle, ...). "observation" is recomputed by the task from ("measured", ...); the true
("state", ...) is left as it is, so metrics and rewards use the truth. Task-held buffers (tracking
errors, integrals) are still fed by the true state inside the env step.

Noise, biases and scale factors come from the transform's own stream on the env's device
(``SeededTransform``: seeded from the env, so ``env.set_seed`` reaches it).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Composite

from ..physics import state as S
from ..physics.rotations import ned_to_body, normalize_quaternion, quaternion_to_euler
from ._buffers import DelayLine, SeededTransform, delay_steps, reset_mask
from ._env import flight_env


@dataclass
class SensorChannel:
    """Error model of one sensor channel (SI units; attitude noise in rad)."""

    noise_std: float = 0.0
    bias: float = 0.0
    #: Std of a constant bias drawn per env and episode.
    bias_std: float = 0.0
    #: Scale-factor error s in y = (1 + s) x.
    scale_factor: float = 0.0
    #: Std of a scale-factor error drawn per env and episode.
    scale_factor_std: float = 0.0
    #: (low, high) clip, or None.
    limits: tuple[float, float] | None = None
    #: Quantisation step (0: none).
    resolution: float = 0.0
    #: Sample rate in Hz (None: every env step), zero-order hold in between.
    rate_hz: float | None = None
    #: Transport delay in ms.
    delay_ms: float = 0.0


#: Sensor name -> the ("state", ...) field it measures.
SENSOR_FIELDS = {"gps_position": "position_ned", "gps_velocity": "velocity_ned", "attitude": "quaternion",
                 "gyro": "angular_rate_body", "airspeed": "airspeed"}


@dataclass
class SensorConfig:
    """Which sensors corrupt the policy's view (None: that field is reported true)."""

    gps_position: SensorChannel | None = None
    gps_velocity: SensorChannel | None = None
    attitude: SensorChannel | None = None
    gyro: SensorChannel | None = None
    airspeed: SensorChannel | None = None
    extra: dict[str, SensorChannel] = field(default_factory=dict)

    def channels(self) -> dict[str, SensorChannel]:
        """State field -> channel, for the sensors that are on."""
        out = {SENSOR_FIELDS[f.name]: getattr(self, f.name) for f in fields(self)
               if f.name in SENSOR_FIELDS and getattr(self, f.name) is not None}
        out.update(self.extra)
        attitude = out.get("quaternion")
        if attitude is not None and (attitude.bias or attitude.bias_std or attitude.scale_factor
                                     or attitude.scale_factor_std or attitude.resolution):
            raise ValueError("the attitude channel takes noise and limits only (then renormalises)")
        return out


class _ChannelState:
    """Per-env state of one channel: episode bias and scale, held sample, delay line."""

    def __init__(self, channel: SensorChannel, value: torch.Tensor, control_dt: float):
        self.channel = channel
        self.period = 1 if channel.rate_hz is None else max(1, round(1.0 / (channel.rate_hz * control_dt)))
        self.bias = torch.zeros_like(value)
        self.scale = torch.ones_like(value)
        self.held = value.clone()
        steps = delay_steps(channel.delay_ms, control_dt)
        self.line = DelayLine(value.shape[0], steps, tuple(value.shape[1:]), value.dtype, value.device)
        self.line.delay.fill_(steps)


class SensorTransform(SeededTransform):
    """Writes ("measured", ...) through the sensor chain and recomputes "observation" from it."""

    def __init__(self, config: SensorConfig, seed: int | None = None):
        super().__init__(seed)
        self.config = config
        self.channels = config.channels()
        self._state: dict[str, _ChannelState] = {}
        self._counter: torch.Tensor | None = None

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        observation_spec["measured"] = observation_spec["state"].clone()
        return observation_spec

    # ------------------------------------------------------------------ chain
    def _randn(self, like: torch.Tensor) -> torch.Tensor:
        generator = self.stream(like.device)
        return torch.randn(like.shape, generator=generator, dtype=like.dtype, device=like.device)

    def _corrupt(self, key: str, x: torch.Tensor, st: _ChannelState) -> torch.Tensor:
        ch = st.channel
        if key == "quaternion":
            y = x + 0.5 * ch.noise_std * self._randn(x) if ch.noise_std else x
            if ch.limits is not None:
                y = y.clamp(*ch.limits)
            return normalize_quaternion(y)
        y = st.scale * x + st.bias
        if ch.noise_std:
            y = y + ch.noise_std * self._randn(x)
        if ch.limits is not None:
            y = y.clamp(*ch.limits)
        if ch.resolution:
            y = torch.round(y / ch.resolution) * ch.resolution
        return y

    def _draw_episode_errors(self, mask: torch.Tensor, x: torch.Tensor, st: _ChannelState) -> None:
        ch = st.channel
        bias = ch.bias + ch.bias_std * self._randn(x)
        scale = 1.0 + ch.scale_factor + ch.scale_factor_std * self._randn(x)
        rows = mask.reshape(-1, *([1] * (x.dim() - 1)))
        st.bias = torch.where(rows, bias, st.bias)
        st.scale = torch.where(rows, scale, st.scale)

    def _measure(self, state: TensorDictBase, mask: torch.Tensor | None) -> TensorDictBase:
        """Run the chain on the true ``state``; ``mask`` [N] = rows being reset (None: a step)."""
        n = state.batch_size[0]
        if self._counter is None:
            self._counter = torch.zeros(n, dtype=torch.long, device=state.device)
        if mask is None:
            self._counter += 1
        else:
            self._counter.masked_fill_(mask, 0)
        out = {}
        for key, channel in self.channels.items():
            x = state.get(key)
            st = self._state.get(key)
            if st is None:
                st = self._state[key] = _ChannelState(channel, x, self.control_dt)
            if mask is not None:
                self._draw_episode_errors(mask, x, st)
            y = self._corrupt(key, x, st)
            sample = (self._counter % st.period == 0) if mask is None else mask
            st.held = torch.where(sample.reshape(-1, *([1] * (x.dim() - 1))), y, st.held)
            if mask is None:
                out[key] = st.line.push(st.held)
            else:
                st.line.fill(mask, st.held)
                out[key] = st.line.last_output()
        return self._assemble(state, out)

    @staticmethod
    def _assemble(state: TensorDictBase, measured: dict[str, torch.Tensor]) -> TensorDictBase:
        fields_ = {k: state.get(k) for k in state.keys()}  # noqa: SIM118 (iterating a td walks the batch)
        fields_.update(measured)
        if "position_ned" in measured and "height" in fields_:
            fields_["height"] = -measured["position_ned"][:, S.DOWN].reshape(fields_["height"].shape)
        q = fields_["quaternion"]
        if "quaternion" in measured and "euler" in fields_:
            fields_["euler"] = quaternion_to_euler(q)
        if ("quaternion" in measured or "velocity_ned" in measured) and "velocity_body" in fields_:
            fields_["velocity_body"] = ned_to_body(q, fields_["velocity_ned"])
        return TensorDict(fields_, batch_size=state.batch_size, device=state.device)

    @property
    def control_dt(self) -> float:
        """Seconds per env step of the base env (its ``control_dt``)."""
        return flight_env(self, "control_dt").control_dt

    def _observe(self, td: TensorDictBase, measured: TensorDictBase) -> TensorDictBase:
        td.set("measured", measured)
        td.set("observation", flight_env(self, "observe").observe(measured))
        return td

    # ------------------------------------------------------------------ TorchRL hooks
    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        mask = reset_mask(tensordict, tensordict_reset.batch_size[0], tensordict_reset.device)
        return self._observe(tensordict_reset, self._measure(tensordict_reset.get("state"), mask))

    def _call(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        return self._observe(next_tensordict, self._measure(next_tensordict.get("state"), None))
