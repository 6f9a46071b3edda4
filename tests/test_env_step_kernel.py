"""The env step as one Warp launch (``physics.fused_env_step``, ``Engine.fuse``) against the same step run
as separate stages (the engine's launch, the task's fused launch, the torch action check, guard and
counters), bit for bit; the crash state inside the engine's kernel against its torch twin; and the
Gymnasium NumPy step against the tensor core."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from falcon_rl.envs import make_env
from falcon_rl.envs.fixed_wing import StepTensors
from falcon_rl.envs.gym import CoreAircraftEnv
from falcon_rl.envs.staged_step import StagedEnvStep
from falcon_rl.envs.tasks import TERMINATION_CODE, AltitudeTask
from falcon_rl.physics import Simulator, warp_backend
from falcon_rl.physics import state as S
from falcon_rl.physics._warp import capture_cpu_graph, init_warp

FUSED_TASKS = ("altitude", "attitude", "path_following", "trajectory", "climb_descend")
N = 16


def staged_step(env, action: torch.Tensor) -> StepTensors:
    """``env``'s step as stages (``StagedEnvStep``: the engine's step, the task's fused launch, the torch
    action check, guard and counters), as the env's :class:`StepTensors`."""
    return StepTensors(*StagedEnvStep(env)(action, with_state=False), None)


def _pair(task: str, **options: object) -> tuple:
    """Two identical envs (same seed), reset."""
    envs = [make_env(task, "volantex_ranger", num_envs=N, backend="warp", seed=5, lean=True, **options)
            for _ in range(2)]
    for env in envs:
        env.reset()
    return tuple(envs)


def _actions(step: int, width: int, generator: torch.Generator) -> torch.Tensor:
    """Uniform actions in [-1.3, 1.3] with, now and then, a NaN row, +-inf, a huge value and float64."""
    action = torch.rand(N, width, generator=generator) * 2.6 - 1.3
    if step % 7 == 3:
        action[1, 0] = float("nan")
        action[2, -1] = float("inf")
        action[3, 0] = -1e30
    return action.double() if step % 5 == 4 else action


def _dive(env: object) -> None:
    """Put the first four envs 0.4 m above the ground, sinking at 12 m/s (they hit it this step)."""
    x = env.sim.x
    x[:4, S.DOWN_INDEX] = -0.4
    x[:4, S.VELOCITY.start + 2] = 12.0


def _assert_same(one: object, two: object) -> None:
    assert torch.equal(one.sim.x, two.sim.x)
    for name in ("crashed", "time", "command", "gust_velocity_body"):
        assert torch.equal(getattr(one.sim, name), getattr(two.sim, name)), name
    assert torch.equal(one.step_count, two.step_count)
    for key, value in one.task.info().items():
        assert torch.equal(value, two.task.info()[key]), key


@pytest.mark.parametrize("task", FUSED_TASKS)
@pytest.mark.parametrize("options", [{}, {"turbulence": "moderate", "wind": (3.0, -2.0, 0.0)}],
                         ids=["calm", "turbulent"])
def test_one_launch_step_equals_the_staged_step(task: str, options: dict) -> None:
    one, two = _pair(task, **options)
    assert one.env_stepper() is not None
    generator = torch.Generator().manual_seed(1)
    seen = torch.zeros(N, dtype=torch.long)
    for step in range(60):
        if step == 20:
            _dive(one), _dive(two)
        action = _actions(step, one.task.action_dim, generator)
        fused = one.step_tensors(action, with_state=False)
        staged = staged_step(two, action)
        for name, a, b in zip(fused._fields, fused, staged, strict=True):
            if a is not None:
                assert torch.equal(a, b), (step, name)
        _assert_same(one, two)
        if step == 20:  # the dive ends on the ground (most of them with the CG: the crash state)
            crashed, x = one.sim.crashed, one.sim.x
            assert int(crashed.sum()) >= 2
            assert (fused.reason[crashed] == TERMINATION_CODE["ground_contact"]).all()
            assert (x[crashed, S.DOWN_INDEX] == 0).all() and (x[crashed, S.VELOCITY] == 0).all()
        seen = torch.maximum(seen, fused.reason)
        done = (fused.reason > 0) | fused.truncated
        if bool(done.any()):
            one.reset_tensors(done), two.reset_tensors(done)
    assert int(seen.max()) > 0  # terminations (ground contact, NaN actions) happened and matched


def test_the_lean_torchrl_step_hands_out_what_the_staged_step_does_in_new_tensors() -> None:
    """The lean TorchRL step (the kernel's outputs and done flags, copied once) against the staged step
    through ``_output``: same keys, values, dtypes and shapes; a rollout keeps every step's values."""
    one, two = _pair("altitude", turbulence="light")
    generator = torch.Generator().manual_seed(3)
    for step in range(40):
        if step == 10:
            _dive(one), _dive(two)
        action = _actions(step, 2, generator).float()
        got = one._step(TensorDict(action=action, batch_size=[N]))
        staged = staged_step(two, action)
        want = two._output(staged.observation, None, staged.reason, staged.truncated.unsqueeze(-1),
                           reward=staged.reward.unsqueeze(-1))
        assert set(got.keys()) == set(want.keys())
        for key in want.keys():  # noqa: SIM118 (iterating a TensorDict gives its rows)
            assert got[key].dtype == want[key].dtype and torch.equal(got[key], want[key]), (step, key)
        # Each output owns its memory (views of one copy cost TorchRL's step more downstream).
        storages = {got[key].untyped_storage().data_ptr() for key in got.keys()}  # noqa: SIM118
        assert len(storages) == len(got.keys()) and all(got[key]._base is None for key in got.keys())  # noqa: SIM118
        done = got["done"].view(N)
        if bool(done.any()):
            one.reset_tensors(done), two.reset_tensors(done)
    rollout = one.rollout(5, break_when_any_done=False)
    assert not torch.equal(rollout["next", "observation"][:, 0], rollout["next", "observation"][:, 4])


def test_the_full_env_checks_the_derived_state_too() -> None:
    """Not lean: the step publishes the state, and a derived field that is not finite terminates the row
    as on the staged path."""
    env = make_env("altitude", "volantex_ranger", num_envs=4, backend="warp", seed=0)
    env.reset()
    env.sim.x[2, S.VELOCITY.start] = float("nan")
    out = env.step_tensors(torch.zeros(4, 2))
    assert out.non_finite.tolist() == [False, False, True, False]
    assert out.reason[2] == env.termination_reasons.index("non_finite")
    assert torch.isfinite(out.observation).all() and torch.isfinite(out.reward).all()


def test_the_one_launch_step_applies_only_where_it_reproduces_the_env() -> None:
    assert make_env("altitude", num_envs=2, backend="warp", seed=0).env_stepper() is not None
    assert make_env("altitude", num_envs=2, backend="torch", seed=0).env_stepper() is None
    assert make_env("altitude", num_envs=2, backend="warp", seed=0, fused=False).env_stepper() is None

    class Scaled(AltitudeTask):
        def command(self, action: torch.Tensor) -> torch.Tensor:
            return super().command(0.5 * action)

    env = make_env("altitude", num_envs=2, backend="warp", seed=0)
    env.task.__class__ = Scaled
    env.__dict__.pop("_env_step", None)
    assert env.env_stepper() is None


def test_the_step_follows_a_new_parameter_set_and_horizon() -> None:
    one, two = _pair("altitude")
    zero = torch.zeros(N, 2)
    one.step_tensors(zero), staged_step(two, zero)
    for env in (one, two):  # a new parameters object (heavier aircraft) and a shorter horizon
        params = env.sim.params
        env.sim.params = type(params)(**{**vars(params), "mass": params.mass * 1.3})
        env.max_episode_steps = 3
    for _ in range(3):
        fused, staged = one.step_tensors(zero), staged_step(two, zero)
        assert torch.equal(fused.observation, staged.observation)
    assert fused.truncated.all() and torch.equal(fused.truncated, staged.truncated)
    _assert_same(one, two)


def test_the_crash_state_in_the_kernel_equals_its_torch_twin() -> None:
    kernel = Simulator("volantex_ranger", num_envs=6, backend="warp", seed=0)
    twin = Simulator("volantex_ranger", num_envs=6, backend="warp", seed=0, stop_at_ground=False)
    for sim in (kernel, twin):
        sim.x[:3, S.DOWN_INDEX] = -0.5
        sim.x[:3, S.VELOCITY.start + 2] = 15.0
    before = torch.empty_like(twin.x)
    command = kernel.command.clone()
    for _ in range(4):
        kernel.step(command, substeps=5)
        before.copy_(twin.x)
        twin.step(command, substeps=5)
        twin.engine.stop_crashed(before)
        assert torch.equal(kernel.x, twin.x) and torch.equal(kernel.crashed, twin.crashed)
    assert kernel.crashed.tolist() == [True] * 3 + [False] * 3
    assert (kernel.x[:3, S.DOWN_INDEX] == 0).all() and (kernel.x[:3, S.VELOCITY] == 0).all()


def _replays_graph(replay: object) -> bool:
    return isinstance(replay, partial) and replay.func is init_warp().capture_launch


@pytest.mark.parametrize("turbulence", [None, "moderate"])
def test_a_captured_cpu_graph_replays_what_the_recorded_launch_does(monkeypatch: pytest.MonkeyPatch,
                                                                    turbulence: str | None) -> None:
    """One CPU slice replays as a captured Warp CPU graph (engine step, derived state, the one-launch env
    step): bit for bit what replaying the recorded launches does, with the sub-step count changing
    between engine steps (the graph is captured again) and terminations and resets in between."""
    def run(captured: bool) -> tuple[list[torch.Tensor], object]:
        if not captured:
            monkeypatch.setattr(warp_backend, "capture_cpu_graph", lambda launch: None)
        env = make_env("altitude", "volantex_ranger", num_envs=3, backend="warp", seed=4, lean=True,
                       turbulence=turbulence)
        env.reset()
        generator, seen = torch.Generator().manual_seed(8), []
        for step in range(30):
            if step == 12:
                _dive(env)
            out = env.step_tensors(_actions(step, 2, generator)[:3])
            derived = env.sim.engine.derived().clone()
            seen += [out.observation, out.reward, out.reason, env.sim.x.clone(), derived]
            env.sim.step(env.sim.command, substeps=1 + step % 3)  # the engine's own launch, re-captured
            done = (out.reason > 0) | out.truncated
            if bool(done.any()):
                env.reset_tensors(done)
        monkeypatch.undo()
        return seen, env

    graph, env = run(captured=True)
    if not _replays_graph(env.env_stepper()._replay):
        pytest.skip("this Warp release has no CPU graphs")
    assert _replays_graph(env.sim.engine._step_replay) and _replays_graph(env.sim.engine._evaluate_replay)
    # each sub-step count the loop used was captured once (a capture costs ~0.5 ms), beside the bound one
    assert sorted(env.sim.engine._step_replays) == [(1, False), (1, True), (2, True), (3, True)]
    launches, plain = run(captured=False)
    assert not _replays_graph(plain.env_stepper()._replay)
    for index, (one, two) in enumerate(zip(graph, launches, strict=True)):
        assert torch.equal(one, two), index


def test_a_launch_that_cannot_be_captured_is_replayed_as_it_is() -> None:
    """A launch that fails to record under the capture gives no graph and leaves no capture open."""
    class Unrecordable:
        def launch(self) -> None:
            raise RuntimeError("cannot record this launch")

    assert capture_cpu_graph(Unrecordable()) is None
    env = make_env("altitude", "volantex_ranger", num_envs=2, backend="warp", seed=0, lean=True)
    env.reset()
    env.step_tensors(torch.zeros(2, 2))  # binds and captures: no capture was left open
    launch = env.env_stepper()._launches[0]
    if capture_cpu_graph(launch) is None:
        pytest.skip("this Warp release has no CPU graphs")


@pytest.mark.parametrize("task", ["altitude", "attitude"])
def test_the_gymnasium_numpy_step_equals_the_tensor_core(task: str) -> None:
    fast, core = (CoreAircraftEnv(task, "volantex_ranger", seed=2) for _ in range(2))
    assert fast.core.numpy_step is not None
    core.core.numpy_step = None  # the tensor core's general path
    rng = np.random.default_rng(0)
    for env in (fast, core):
        env.reset(seed=4)
    for step in range(80):
        action = rng.uniform(-1.2, 1.2, fast.action_space.shape)
        if step % 9 == 4:
            action[0] = np.nan
        action = action if step % 2 else action.astype(np.float32)
        one, two = fast.step(action), core.step(action)
        np.testing.assert_array_equal(one[0], two[0])
        assert one[1:4] == two[1:4]
        assert one[4].keys() == two[4].keys()
        for key in one[4]:
            np.testing.assert_array_equal(one[4][key], two[4][key])
        if one[2] or one[3]:
            fast.reset(), core.reset()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
@pytest.mark.parametrize("task", ["altitude", "attitude"])
def test_one_launch_step_equals_the_staged_step_on_cuda(task: str) -> None:
    envs = [make_env(task, "volantex_ranger", num_envs=256, backend="warp", device="cuda", seed=5, lean=True)
            for _ in range(2)]
    for env in envs:
        env.reset()
    one, two = envs
    generator = torch.Generator().manual_seed(1)
    for step in range(30):
        action = _actions(step, one.task.action_dim, generator)[:1].expand(256, -1).cuda()
        fused, staged = one.step_tensors(action, with_state=False), staged_step(two, action)
        for name, a, b in zip(fused._fields, fused, staged, strict=True):
            if a is None:
                continue
            if a.is_floating_point():  # the CUDA compiler may contract a*b+c differently per module
                torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-4, msg=f"{step} {name}")
            else:
                assert torch.equal(a, b), (step, name)
        torch.testing.assert_close(one.sim.x, two.sim.x, rtol=1e-4, atol=1e-4)


def _generator_states(task: object) -> dict[int, torch.Tensor]:
    """id -> state of every torch generator the task holds (its own and its command stream's)."""
    generators = [task.generator]
    stream = getattr(task, "random_stream", None)
    if stream is not None:
        generators.append(stream.generator)
    return {id(g): g.get_state() for g in generators}


@pytest.mark.parametrize(("task", "options"), [
    ("altitude", {}), ("altitude", {"target_sequence": True}), ("attitude", {}),
    ("attitude", {"maneuver": "s_turn"}), ("path_following", {}), ("trajectory", {})])
def test_a_fused_step_names_every_generator_its_draws_use(task: str, options: dict) -> None:
    """A CUDA graph of the step registers ``generators()``; a draw from any other would replay the
    numbers of the capture."""
    env = make_env(task, "volantex_ranger", num_envs=4, backend="warp", seed=3, lean=True, **options)
    env.reset()
    step = env.env_stepper().task_step
    before = _generator_states(env.task)
    step.draw()
    moved = {key for key, state in _generator_states(env.task).items() if not torch.equal(state, before[key])}
    assert moved == {id(g) for g in step.generators()}


def test_a_cuda_graph_of_the_step_needs_cuda() -> None:
    env = make_env("altitude", "volantex_ranger", num_envs=2, backend="warp", seed=0, lean=True)
    with pytest.raises(ValueError, match="needs a CUDA device"):
        env.env_stepper().cuda_graph()


@pytest.mark.gpu
@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_the_cuda_graph_of_the_step_replays_what_the_launch_does() -> None:
    """Altitude (whose CUDA kernels are the ones built ahead) with turbulence (the device-side noise
    counter) and a target sequence (draws from a generator registered with the graph)."""
    options = {"turbulence": "moderate", "target_sequence": True, "capture_band": 1000.0, "hold_seconds": 0.3}
    envs = [make_env("altitude", "volantex_ranger", num_envs=512, backend="warp", device="cuda", seed=5,
                     lean=True, **options) for _ in range(2)]
    for env in envs:
        env.reset()
    graphed, launched = (env.env_stepper() for env in envs)
    for _ in range(3):  # a first step loads the CUDA kernels the capture records
        graphed.launch(), launched.launch()
    replay = graphed.cuda_graph()
    assert torch.equal(envs[0].sim.x, envs[1].sim.x)  # capturing ran nothing
    generator = torch.Generator().manual_seed(2)
    for step in range(25):
        action = (torch.rand(512, envs[0].task.action_dim, generator=generator) * 2 - 1).cuda()
        graphed.raw_action.copy_(action)
        launched.raw_action.copy_(action)
        replay()
        launched.launch()
        for name in ("observation", "reward", "reason"):
            one, two = getattr(graphed.task_step, name), getattr(launched.task_step, name)
            assert torch.equal(one, two), (step, name)
        assert torch.equal(graphed.flags, launched.flags) and torch.equal(envs[0].sim.x, envs[1].sim.x), step
    envs[0].max_episode_steps += 1  # the step binds again: the graph is stale
    with pytest.raises(RuntimeError, match="capture a new one"):
        replay()
