"""Every task's Warp step (its one body, ``Task.fused_stepper``) against an independent torch reference
of the task's equations (``tests/task_references.py``, ``Task.torch_step`` on ``Simulator.state``): same
observations, rewards, done flags, termination reasons, ("task", ...) and ("state", ...) entries over
rollouts with auto-resets, on several airframes, decimations, turbulence and wind (on CUDA too, skipped
without a GPU); the lean env against the full one; crafted crashes; float64 envs; what a task with a Warp
step refuses; pickling and re-binding after a parameter tensor is replaced."""

from __future__ import annotations

import math
import pickle

import pytest
import torch
from task_references import torch_reference
from tensordict import TensorDictBase
from torchrl.envs import EnvBase

from falcon_rl import make_env
from falcon_rl.envs.tasks import TERMINATION_CODE, AltitudeTask
from falcon_rl.physics import state as S
from falcon_rl.physics._warp import warp_cuda_available
from falcon_rl.physics.rotations import euler_to_quaternion

N = 8
WIND = (3.0, -2.0, 0.5)
#: float32 tolerance: the kernel and torch may differ in the last bits (exp, division by a scalar).
TOL = {"rtol": 1e-5, "atol": 1e-5}
#: Every buffer ``AltitudeTask.step`` updates.
TASK_BUFFERS = ("time", "segment_time", "time_in_band", "error_integral", "previous_elevator",
                "elevator_rate", "previous_action", "target", "initial_altitude", "segment_start",
                "reference", "reference_rate", "altitude_error", "reference_error", "climb_rate",
                "previous_airspeed", "airspeed_rate")


class HeldRandomPolicy:
    """Random actions [N, A], mostly at the extremes, each held for ``hold`` steps plus a little noise:
    they fly the envs into stalls and the ground, so rollouts see terminations and auto-resets."""

    def __init__(self, shape: torch.Size, seed: int, hold: int):
        self.generator = torch.Generator().manual_seed(seed)
        self.shape, self.hold, self.count = shape, hold, 0
        self.action = torch.zeros(shape)

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        if self.count % self.hold == 0:
            self.action = (torch.rand(self.shape, generator=self.generator) * 2.4 - 1.2).clamp(-1.0, 1.0)
        self.count += 1
        noise = 0.1 * torch.randn(self.shape, generator=self.generator)
        td["action"] = (self.action + noise).to(td.device)
        return td


def altitude_env(airframe: str = "navion", fused: bool = True, **options) -> EnvBase:
    """An altitude env on the warp engine: its Warp step, or (``fused=False``) the torch reference."""
    options = {"num_envs": N, "seed": 3, "wind": WIND, "episode_seconds": 4.0, **options}
    env = make_env("altitude", airframe, backend="warp", **options)
    return env if fused else torch_reference(env)


def roll(env: EnvBase, steps: int, hold_seconds: float = 2.0) -> TensorDictBase:
    """A rollout of ``steps`` steps with auto-resets, actions held ``hold_seconds``."""
    hold = max(1, round(hold_seconds / env.control_dt))
    return env.rollout(steps, HeldRandomPolicy(env.action_spec.shape, 0, hold), break_when_any_done=False)


def assert_same_rollout(expected: TensorDictBase, actual: TensorDictBase, keys: list | None = None) -> None:
    """Every entry (or those of ``keys``) equal: floats to float32 tolerance, flags and codes exactly."""
    for key in keys if keys is not None else expected.keys(True, True):
        a, b = expected[key], actual[key]
        if a.is_floating_point():
            torch.testing.assert_close(b, a, **TOL, msg=lambda m, key=key: f"{key}: {m}")
        else:
            assert torch.equal(a, b), key


@pytest.mark.parametrize(("airframe", "decimation", "turbulence"), [
    ("navion", 5, None), ("navion", 1, "moderate"), ("volantex_ranger", 5, "moderate"),
    ("volantex_ranger", 1, None), ("airship_v7", 5, None), ("airship_v7", 1, "moderate"),
])
def test_fused_rollout_matches_the_torch_step(airframe, decimation, turbulence):
    steps = 300 if decimation == 5 else 450
    envs = {fused: altitude_env(airframe, fused, decimation=decimation, turbulence=turbulence)
            for fused in (False, True)}
    runs = {fused: roll(env, steps) for fused, env in envs.items()}
    reference = runs[False]
    assert_same_rollout(reference, runs[True])
    for name in TASK_BUFFERS:
        expected, actual = getattr(envs[False].task, name), getattr(envs[True].task, name)
        torch.testing.assert_close(actual, expected, **TOL, msg=lambda m, name=name: f"{name}: {m}")
    assert set(reference.keys(True, True)) == set(runs[True].keys(True, True))
    reasons = reference["next", "termination_reason"]
    assert (reasons > 0).any(), "the rollout should see terminations"
    assert reference["next", "truncated"].any(), "the rollout should see truncations"


def test_energy_rate_term_matches_the_torch_step_and_changes_the_reward():
    options = {"decimation": 5, "turbulence": "moderate", "w_energy_rate": 0.5}
    envs = {fused: altitude_env("airship_v7", fused, **options) for fused in (False, True)}
    runs = {fused: roll(env, 300) for fused, env in envs.items()}
    assert_same_rollout(runs[False], runs[True])
    for name in ("previous_airspeed", "airspeed_rate"):
        torch.testing.assert_close(getattr(envs[True].task, name), getattr(envs[False].task, name), **TOL)
    without = roll(altitude_env("airship_v7", True, decimation=5, turbulence="moderate"), 300)
    assert_same_rollout(without, runs[True], [("next", "observation")])
    assert (without["next", "reward"] - runs[True]["next", "reward"]).max() > 0.01, "the term should cost"


def test_lean_fused_env_streams_what_the_full_env_does():
    full = roll(altitude_env("airship_v7", fused=False, decimation=5, turbulence="light"), 300)
    lean = roll(altitude_env("airship_v7", fused=True, decimation=5, turbulence="light", lean=True), 300)
    keys = [*(("next", k) for k in ("observation", "reward", "done", "terminated", "truncated",
                                      "termination_reason")), "observation", "done"]
    assert_same_rollout(full, lean, keys)
    assert lean.get(("next", "state"), None) is None and (full["next", "termination_reason"] > 0).any()


def test_target_sequence_draws_and_releases_as_the_torch_step():
    options = {"target_sequence": True, "capture_band": 1000.0, "hold_seconds": 0.3, "decimation": 5}
    runs = {fused: roll(altitude_env("volantex_ranger", fused, **options), 200) for fused in (False, True)}
    assert_same_rollout(runs[False], runs[True])
    released = runs[False]["next", "task", "target_altitude"] != runs[False]["task", "target_altitude"]
    assert released.sum() > runs[False]["next", "done"].sum(), "targets should be released mid-episode"


def test_climb_descend_task_is_fused_too():
    runs = {fused: roll(task_env("climb_descend", fused=fused, seed=5, wind=None), 120)
            for fused in (False, True)}
    assert_same_rollout(runs[False], runs[True])


def crafted_states(env: EnvBase) -> list[int]:
    """Write crashing rows into the env's state (after a reset); returns the reasons expected after
    one step: CG contact, wing-tip contact, alpha stall, speed stall, NaN, flying, and two rows where
    several apply (the first in TERMINATION_REASONS wins)."""
    x = env.sim.x
    deg = math.pi / 180.0

    def put(row: int, height: float, velocity: tuple[float, float, float], roll: float = 0.0) -> None:
        x[row, S.DOWN_INDEX] = -height
        x[row, S.QUATERNION] = euler_to_quaternion(torch.tensor([[roll * deg, 0.0, 0.0]]))[0]
        x[row, S.VELOCITY] = torch.tensor(velocity)
        x[row, S.ANGULAR_RATE] = 0.0

    put(0, 0.02, (53.0, 0.0, 3.0))  # sinks through the ground
    put(1, 1.5, (53.0, 0.0, 0.0), roll=80.0)  # CG above ground, lower wing tip below
    put(2, 100.0, (37.0, 0.0, 37.0))  # alpha 45 deg > 1.5 x 20 deg
    put(3, 100.0, (10.0, 0.0, 0.0))  # 10 m/s < V_stall 25.3 m/s
    x[4, S.ANGULAR_RATE] = float("nan")
    put(6, 0.02, (10.0, 0.0, 3.0))  # ground contact and speed stall
    put(7, 100.0, (12.0, 0.0, 14.0))  # alpha stall and speed stall
    code = TERMINATION_CODE
    return [code["ground_contact"], code["ground_contact"], code["alpha_stall"], code["speed_stall"],
            code["non_finite"], 0, code["ground_contact"], code["alpha_stall"]]


@pytest.mark.parametrize("lean", [False, True])
def test_crafted_crashes_give_the_same_reasons(lean):
    out = {}
    for fused in (False, True):
        env = altitude_env("navion", fused, decimation=1, wind=None, lean=lean)
        td = env.reset()
        expected = crafted_states(env)
        td["action"] = env.trim_action().expand(N, -1).clone()
        out[fused] = env.step(td)["next"]
        assert out[fused]["termination_reason"].flatten().tolist() == expected
    assert_same_rollout(out[False], out[True])
    for value in out[True].values(True, True):
        assert not value.is_floating_point() or torch.isfinite(value).all()


@pytest.mark.parametrize("task", ["altitude", "attitude", "path_following", "trajectory", "climb_descend"])
def test_a_float64_env_runs_the_warp_step_on_float32_copies(task):
    """A float64 env (torch engine) steps its task with the same Warp body, on float32 copies of the state:
    its rollout is the float64 torch reference's to float32 precision, in float64 entries."""
    def env(fused: bool) -> EnvBase:
        made = make_env(task, "volantex_ranger", num_envs=N, backend="torch", seed=3, wind=WIND,
                        episode_seconds=3.0, dtype=torch.float64)
        return made if fused else torch_reference(made)

    envs = {fused: env(fused) for fused in (False, True)}
    assert envs[True].task.buffer_dtype == torch.float32 and envs[False].task.buffer_dtype == torch.float64
    runs = {fused: roll(made, 90, hold_seconds=1.0) for fused, made in envs.items()}
    assert runs[True]["next", "observation"].dtype == torch.float64
    assert runs[True]["next", "reward"].dtype == torch.float64
    assert int(runs[True]["next", "done"].sum()) > 0
    for key in runs[False].keys(True, True):
        a, b = runs[False][key], runs[True][key]
        if a.is_floating_point():  # float32 task arithmetic against float64
            torch.testing.assert_close(b, a, rtol=1e-4, atol=2e-3 if "position" in str(key) else 1e-4,
                                       msg=lambda m, key=key: f"{key}: {m}")
        else:
            assert torch.equal(a, b), key


def test_a_task_with_a_warp_step_refuses_torch_step_methods():
    """A subclass that would change a built-in task's reward (or any part of its step) in torch is refused
    when built: its Warp step would never run the change."""
    class Changed(AltitudeTask):
        def reward(self, state, action):
            return super().reward(state, action) + 1.0

    env = altitude_env("navion")
    with pytest.raises(TypeError, match=r"Changed defines reward, but its step is its Warp functions"):
        Changed(env.task.config, env.sim, env.generator, env.control_dt)
    with pytest.raises(TypeError, match=r"call step\(action\)"):
        env.task.torch_step(env.sim.state, torch.zeros(N, 2))


def test_pickled_fused_env_continues_the_same_stream():
    env = altitude_env("volantex_ranger", decimation=5, turbulence="light")
    roll(env, 40)
    copy = pickle.loads(pickle.dumps(env))
    assert copy.task._fused is None
    td = env.reset()
    assert_same_rollout(td, copy.reset())
    assert_same_rollout(roll(env, 60), roll(copy, 60))


def test_replaced_parameter_tensor_is_rebound():
    runs = {}
    for fused in (False, True):
        env = altitude_env("navion", fused, decimation=5)
        roll(env, 20)
        params = env.sim.params
        params.span = params.span * 3.0  # a new tensor: wing tips reach the ground at smaller rolls
        params.surface_max = params.surface_max * 0.5
        env.sim.engine.rebind()
        runs[fused] = roll(env, 150)
    assert_same_rollout(runs[False], runs[True])


def test_unequal_motor_throttles_are_observed_as_their_mean():
    out = {}
    for fused in (False, True):
        env = altitude_env("airship_v7", fused, decimation=1)
        td = env.reset()
        env.sim.x[:, S.THROTTLE_START] = torch.linspace(0.0, 0.4, N)
        env.sim.x[:, S.THROTTLE_START + 1] = torch.linspace(1.0, 0.6, N)
        td["action"] = env.trim_action().expand(N, -1).clone()
        out[fused] = env.step(td)["next"]
        throttle = out[fused]["state", "throttle"]
        assert (throttle[:, 0] - throttle[:, 1]).abs().min() > 0.1
    assert_same_rollout(out[False], out[True])


def test_threaded_cpu_slices_match():
    runs = {}
    for fused in (False, True):
        env = altitude_env("navion", fused, num_envs=16, warp_cpu_threads=2, turbulence="light")
        assert len(env.sim.engine.slices) > 1
        runs[fused] = roll(env, 100)
    assert_same_rollout(runs[False], runs[True])


@pytest.mark.gpu
@pytest.mark.skipif(not warp_cuda_available(), reason="needs CUDA (torch and warp)")
@pytest.mark.parametrize("options", [{"turbulence": "moderate"}, {"decimation": 1, "lean": True},
                                     {"target_sequence": True, "capture_band": 1000.0, "hold_seconds": 0.3}])
def test_fused_rollout_matches_on_cuda(options):
    runs = {fused: roll(altitude_env("volantex_ranger", fused, num_envs=64, device="cuda", **options), 300)
            for fused in (False, True)}
    assert_same_rollout(runs[False], runs[True])
    assert runs[True]["next", "observation"].device.type == "cuda"


# ---------------------------------------------------------------------------- the other tasks' fused steps
#: Every buffer each task's ``step`` updates (dotted: an attribute of an attribute).
OTHER_TASK_BUFFERS: dict[str, tuple[str, ...]] = {
    "attitude": ("time", "step_index", "commanded", "errors", "previous_action", "random_stream.command",
                 "random_stream.target", "random_stream.timer"),
    "path_following": ("time", "path_point", "path_course", "errors", "previous_action"),
    "trajectory": ("time", "start", "radius", "turn", "climb", "reference_position", "reference_velocity",
                   "position_error", "velocity_error", "position_error_ned", "previous_action"),
}
#: Absolute tolerance (m) of the trajectory's positions: its reference R (1 - cos wt), with R up to a few
#: km, turns a 1-ulp difference of cos (torch's SLEEF against the C library) into ~1e-4 m.
POSITION_ATOL = {"reference_position": 1e-3, "position_error_ned": 1e-3, "position_error": 1e-3}


def task_env(task: str, airframe: str = "navion", fused: bool = True, **options) -> EnvBase:
    """A ``task`` env on the warp engine: its Warp step, or (``fused=False``) the torch reference."""
    options = {"num_envs": N, "seed": 3, "wind": WIND, "episode_seconds": 4.0, **options}
    env = make_env(task, airframe, backend="warp", **options)
    return env if fused else torch_reference(env)


def assert_close_entries(expected: TensorDictBase, actual: TensorDictBase, keys: list | None = None) -> None:
    """:func:`assert_same_rollout` with the trajectory's position tolerance on its position entries."""
    for key in keys if keys is not None else expected.keys(True, True):
        a, b = expected[key], actual[key]
        name = key[-1] if isinstance(key, tuple) else key
        if a.is_floating_point():
            tol = {**TOL, "atol": POSITION_ATOL.get(name, TOL["atol"])}
            torch.testing.assert_close(b, a, **tol, msg=lambda m, key=key: f"{key}: {m}")
        else:
            assert torch.equal(a, b), key


def task_buffer(task: object, name: str) -> torch.Tensor:
    for part in name.split("."):
        task = getattr(task, part)
    assert isinstance(task, torch.Tensor)
    return task


@pytest.mark.parametrize(("task", "airframe", "decimation", "options"), [
    ("attitude", "navion", 5, {}),
    ("attitude", "volantex_ranger", 1, {"turbulence": "moderate"}),
    ("attitude", "airship_v7", 5, {"turbulence": "moderate"}),
    ("attitude", "volantex_ranger", 5, {"maneuver": "s_turn"}),
    ("attitude", "navion", 1, {"maneuver": "figure8", "turbulence": "light"}),
    ("path_following", "navion", 5, {"lost_distance": 25.0}),
    ("path_following", "volantex_ranger", 1, {"turbulence": "moderate"}),
    ("path_following", "airship_v7", 5, {"turbulence": "moderate", "lost_distance": 15.0}),
    ("trajectory", "navion", 1, {"turbulence": "moderate", "lost_distance": 40.0}),
    ("trajectory", "volantex_ranger", 5, {}),
    ("trajectory", "airship_v7", 1, {"lost_distance": 30.0}),
])
def test_fused_task_rollout_matches_the_torch_step(task, airframe, decimation, options):
    envs = {fused: task_env(task, airframe, fused, decimation=decimation, **options)
            for fused in (False, True)}
    runs = {fused: roll(env, 300 if decimation == 5 else 400) for fused, env in envs.items()}
    reference = runs[False]
    assert envs[True].task._fused is not None and envs[False].task._fused is None
    assert set(reference.keys(True, True)) == set(runs[True].keys(True, True))
    assert_close_entries(reference, runs[True])
    for name in OTHER_TASK_BUFFERS[task]:
        if name.startswith("random_stream") and envs[False].task.random_stream is None:
            continue
        expected, actual = task_buffer(envs[False].task, name), task_buffer(envs[True].task, name)
        tol = {**TOL, "atol": POSITION_ATOL.get(name, TOL["atol"])}
        torch.testing.assert_close(actual, expected, **tol, msg=lambda m, name=name: f"{name}: {m}")
    assert torch.equal(envs[False].task.generator.get_state(), envs[True].task.generator.get_state())
    reasons = reference["next", "termination_reason"]
    assert (reasons > 0).any(), "the rollout should see terminations"
    if "lost_distance" in options:
        assert (reasons == TERMINATION_CODE["lost"]).any(), "the rollout should see lost envs"
    if not {"maneuver", "lost_distance"} & set(options):  # a maneuver lasts its stream; lost envs end early
        assert reference["next", "truncated"].any(), "the rollout should see truncations"


class HeldAction:
    """The same action [N, A] every step."""

    def __init__(self, action: torch.Tensor):
        self.action = action

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        return td.set("action", self.action.clone())


def test_random_command_streams_redraw_as_the_torch_step():
    """Trim-held flights of 25 s: every env's stream target expires (holds last 3-10 s) at least twice."""
    runs, envs = {}, {}
    for fused in (False, True):
        env = envs[fused] = task_env("attitude", "volantex_ranger", fused, wind=None, episode_seconds=25.0,
                                     decimation=5)
        runs[fused] = env.rollout(500, HeldAction(env.trim_action().expand(N, -1).clone()),
                                  break_when_any_done=False)
    assert (runs[False]["next", "termination_reason"] == 0).all() and runs[False]["next", "truncated"].any()
    assert_close_entries(runs[False], runs[True])
    for name in OTHER_TASK_BUFFERS["attitude"]:
        torch.testing.assert_close(task_buffer(envs[True].task, name), task_buffer(envs[False].task, name),
                                   **TOL)


@pytest.mark.parametrize("task", ["attitude", "path_following", "trajectory"])
def test_lean_fused_task_env_streams_what_the_full_env_does(task):
    options = {"decimation": 5, "turbulence": "light"}
    full = roll(task_env(task, "airship_v7", fused=False, **options), 200)
    lean = roll(task_env(task, "airship_v7", fused=True, lean=True, **options), 200)
    keys = [*(("next", k) for k in ("observation", "reward", "done", "terminated", "truncated",
                                      "termination_reason")), "observation", "done"]
    assert_close_entries(full, lean, keys)
    assert lean.get(("next", "state"), None) is None and (full["next", "termination_reason"] > 0).any()


@pytest.mark.parametrize("task", ["attitude", "path_following", "trajectory"])
def test_crafted_crashes_give_the_same_reasons_in_every_task(task):
    lost = task != "attitude"
    out = {}
    for fused in (False, True):
        env = task_env(task, "navion", fused, decimation=1, wind=None)
        td = env.reset()
        expected = crafted_states(env)
        if lost:  # far off the path: row 5 is lost, row 6 touches the ground first
            env.sim.x[5:7, S.POSITION.start + 1] = 5000.0
            expected[5] = TERMINATION_CODE["lost"]
        td["action"] = env.trim_action().expand(N, -1).clone()
        out[fused] = env.step(td)["next"]
        assert out[fused]["termination_reason"].flatten().tolist() == expected
    assert_close_entries(out[False], out[True])


def test_every_registered_task_has_a_fused_warp_step():
    from falcon_rl.envs.tasks import TASK_SPECS

    names = [name for name, spec in TASK_SPECS.items() if spec.task.__module__.startswith("falcon_rl.envs.")]
    assert {"altitude", "climb_descend", "attitude", "path_following", "trajectory"} <= set(names)
    for name in names:
        assert TASK_SPECS[name].task.has_warp_step(), name
        for backend, dtype in (("warp", torch.float32), ("torch", torch.float32), ("torch", torch.float64)):
            env = make_env(name, "navion", num_envs=2, backend=backend, seed=0, dtype=dtype)
            action = torch.zeros(2, env.task.action_dim, dtype=dtype)
            assert env.task.fused_stepper() is not None, name
            observation, reward, reason = env.task.step(action)
            assert observation.shape == (2, env.task.observation_dim) and reward.shape == reason.shape == (2,)


CUDA = pytest.param("cuda", marks=pytest.mark.skipif(not warp_cuda_available(), reason="needs CUDA"))


@pytest.mark.parametrize("device", ["cpu", CUDA])
@pytest.mark.parametrize("task", ["altitude", "attitude", "path_following", "trajectory", "climb_descend"])
def test_on_the_torch_engine_the_fused_step_matches_the_torch_step(task, device):
    """The torch engine runs the task's Warp step after its torch physics (on torch's stream on a GPU):
    the same rollout as the task's torch reference on the same engine, auto-resets and terminations
    included."""
    envs = {fused: make_env(task, "volantex_ranger", num_envs=N, backend="torch", seed=3, wind=WIND,
                            episode_seconds=3.0, device=device) for fused in (False, True)}
    torch_reference(envs[False])
    assert envs[True].task.fused_stepper() is not None and envs[False].task.fused_stepper() is None
    rollouts = {fused: roll(env, 90, hold_seconds=1.0) for fused, env in envs.items()}
    assert int(rollouts[True]["next", "done"].sum()) > 0
    assert_same_rollout(rollouts[False], rollouts[True])


def test_other_tasks_refuse_a_changed_step_or_stream():
    from falcon_rl.envs.maneuvers import RandomCommandStream
    from falcon_rl.envs.tasks import AttitudeTask, TrajectoryTask

    class Changed(TrajectoryTask):
        def observe(self, state):
            return super().observe(state)

    class Stream(RandomCommandStream):
        pass

    env = task_env("trajectory")
    with pytest.raises(TypeError, match="Changed defines observe"):
        Changed(env.task.config, env.sim, env.generator, env.control_dt)
    env = task_env("attitude")
    assert isinstance(env.task, AttitudeTask) and env.task.random_stream is not None
    env.task.random_stream.__class__ = Stream
    env.task._fused = None
    with pytest.raises(TypeError, match="RandomCommandStream process; a Stream cannot be stepped"):
        env.task.fused_stepper()


def test_pickled_fused_attitude_env_continues_the_same_stream():
    env = task_env("attitude", "volantex_ranger", decimation=5, turbulence="light", warp_cpu_threads=2,
                   num_envs=16)
    assert len(env.sim.engine.slices) > 1
    roll(env, 40)
    copy = pickle.loads(pickle.dumps(env))
    assert copy.task._fused is None
    assert_close_entries(env.reset(), copy.reset())
    assert_close_entries(roll(env, 60), roll(copy, 60))


@pytest.mark.gpu
@pytest.mark.skipif(not warp_cuda_available(), reason="needs CUDA (torch and warp)")
@pytest.mark.parametrize(("task", "options"), [
    ("attitude", {"turbulence": "moderate"}), ("attitude", {"maneuver": "helix", "lean": True}),
    ("path_following", {"turbulence": "moderate", "lost_distance": 25.0}),
    ("trajectory", {"decimation": 1, "lost_distance": 40.0}),
])
def test_fused_task_rollout_matches_on_cuda(task, options):
    runs = {fused: roll(task_env(task, "volantex_ranger", fused, num_envs=64, device="cuda", **options), 300)
            for fused in (False, True)}
    assert_close_entries(runs[False], runs[True])
    assert runs[True]["next", "observation"].device.type == "cuda"
