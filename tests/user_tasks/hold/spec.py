"""The throttle hold task's record (registered by the test that uses it)."""

from falcon_rl.envs.tasks import TRIM_HOLD, Metric, TaskSpec

from .task import HoldConfig, HoldTask

SPEC = TaskSpec(name="user_hold", task=HoldTask, config=HoldConfig, gym_id="falcon_rl_test/UserHold-v0",
                title="Throttle height hold (a user's task)",
                protocol="falcon_rl.evaluation.protocols:altitude_protocol",
                metrics=(Metric("survival", "Surv."),), controllers={"trim": TRIM_HOLD})
