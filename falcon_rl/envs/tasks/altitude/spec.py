"""The altitude acquisition and hold task's record: its protocol, metrics, baselines, figure and training
defaults (:class:`~falcon_rl.envs.tasks.registry.TaskSpec`), registered on import."""

from __future__ import annotations

from ..registry import TRAINING_DECIMATION, TRIM_HOLD, Metric, TaskSpec, register_task
from .task import AltitudeConfig, AltitudeTask

#: The env this task is built with by default and every recipe trains on: control at 20 Hz
#: (decimation 5 of the 10 ms physics step), so that gamma 0.99 looks ~5 s ahead; a survival bonus
#: that outweighs the shaping penalties (ending an episode never pays); no overshoot penalty; sigma_h
#: 6 m so the Gaussian altitude term still has a gradient 10-15 m from the reference. The paper's
#: reward is ``survival_bonus=0, w_overshoot=<AltitudeConfig's>, sigma_altitude=<AltitudeConfig's>``.
TRAINING_ENV_OPTIONS: dict = {"decimation": TRAINING_DECIMATION, "survival_bonus": 1.0, "w_overshoot": 0.0,
                              "sigma_altitude": 6.0}

#: The paper's altitude protocol columns (Table "altitude-protocol").
ALTITUDE_METRICS: tuple[Metric, ...] = (
    Metric("survival", "Surv."), Metric("acquisition", "Acq."), Metric("rmse_m", "RMSE", "m"),
    Metric("settling_time_s", "t_s", "s"), Metric("overshoot_m", "Over.", "m"))

#: "Solved" on the altitude protocol, as a recipe's ``stop_when``: every episode survives, >= 95 % acquire
#: the target band and the RMSE after acquisition is <= 0.5 m (``falcon-rl demo --train`` stops there).
ALTITUDE_SOLVED = "survival>=1,acquisition>=0.95,rmse_m<=0.5"

#: The off-policy critics of the altitude task: 5-step returns and layer norm in the critics. With
#: one-step targets and plain critics (the recipes' defaults) neither SAC nor TD3 settled on the Ranger
#: (validation RMSE moving 0.35-1.9 m between snapshots up to 500 k frames; a slow, badly damped capture
#: after descents); with these, SAC's validations fell steadily to 0.06 m by 350 k frames and TD3's to
#: 0.009 m by 600 k (seed 0; falcon_rl/policies/README.md).
OFF_POLICY_CRITIC: dict = {"n_step": 5, "critic_layer_norm": True}

#: The Airship V7's off-policy episodes: 40 s and 700 k frames. Its climb-rate limit is 0.83 m/s, so the
#: 12-18 m ramp alone takes 14.5-21.7 s and 20 s episodes end on the ramp or a few seconds into the hold;
#: SAC trained on them (seed 0, 400 k frames) never learned to hold: it settled 0.9-1.7 m below the
#: target with a steady throttle (100-episode protocol: RMSE 1.39 m, acquisition 0.40). With these, SAC
#: seeds 0 / 1 / 2 tested 0.27 / 0.80 / 0.006 m (acquisition 0.96 / 0.83 / 1; seeds 0 and 1 hold the V7
#: 2-7 m/s below its trim airspeed) and TD3 seed 0 0.66 m (0.76), hence :data:`V7_SAC` and :data:`V7_TD3`.
V7_OFF_POLICY: dict = {"episode_seconds": 40.0, "frames": 700_000}

#: The specific energy-rate penalty weighted 0.5 (``w_energy_rate``; 0 in the paper's reward). The
#: V7 climbs at its reference rate only near full throttle (trim command +0.49): SAC seeds 0 and 1 on
#: :data:`V7_OFF_POLICY` climbed on the elevator instead (throttle command 0.42-0.47 over the ramps,
#: seed 2: 0.92), traded 28 -> 22-24 m/s for height and held the target slow. The airspeed penalty
#: answers a throttle change only as the speed builds, seconds later; the energy-rate error answers it
#: at once, and a pitch-up alone cannot meet a ramp's energy rate.
ENERGY_RATE_PENALTY: dict = {"w_energy_rate": 0.5}

#: The Airship V7's SAC altitude: :data:`V7_OFF_POLICY` and :data:`ENERGY_RATE_PENALTY`. Seeds 0 / 1 / 2
#: tested 0.014 / 0.018 / 0.014 m, acquisition 1, climbing at throttle 0.91-0.96 at the trim airspeed (on
#: :data:`V7_OFF_POLICY` alone: 0.271 / 0.802 / 0.006 m, acquisition 0.96 / 0.83 / 1; every variant tried
#: is in falcon_rl/policies/README.md).
V7_SAC: dict = {**V7_OFF_POLICY, "env_options": ENERGY_RATE_PENALTY}

#: The airspeed penalty weighted 2.0 instead of 0.5 (``w_airspeed``; the paper's reward, one weight
#: changed), for the off-policy runs that settle off the trim airspeed: more than 5 % from it the capture
#: term ``taper(e_h, 1 m) * taper(e_V, 5 %)`` pays nothing and the Gaussian altitude term is flat within a
#: metre, so only the airspeed penalty leads the policy back to trim and the last metre.
HEAVIER_AIRSPEED_PENALTY: dict = {"w_airspeed": 2.0}

#: The Airship V7's TD3 altitude: :data:`V7_OFF_POLICY`, 600 k frames and
#: :data:`HEAVIER_AIRSPEED_PENALTY`. On the defaults TD3 held the V7 2-3 m/s below its trim airspeed
#: (seed 0: 0.663 m, acquisition 0.76; gamma 0.995 or 10-step returns: validations 1.9-8 m at 400 k
#: frames); with the heavier airspeed term it flies at trim and seeds 0 / 1 / 2 tested 0.132 / 0.077 /
#: 0.010 m, acquisition 1 (falcon_rl/policies/README.md).
V7_TD3: dict = {**V7_OFF_POLICY, "frames": 600_000, "env_options": HEAVIER_AIRSPEED_PENALTY}

#: The Airship V7's PPO altitude: 30 s episodes (the longest ramp, 21.7 s, and the 3 s hold fit), gamma
#: 0.995, validation every 100 k frames, and training starts |h_0 - h*| ~ U(0, 18) m instead of the
#: protocol's U(12, 18) (``offset_min`` 0; the validation and the test keep the paper's offsets). On
#: 12-18 m starts alone the ramp fills most of each episode and the hold is learnt from few steps: it
#: settled with an offset that changed from snapshot to snapshot (validations 0.1-6.8 m over the last 4 M
#: frames of seed 0; tests 0.111 / 0.048 / 0.076 m on seeds 0 / 1 / 2), and from a start at the target
#: (the ground-effect study's pinned hold) 0.3-1 m off, so h/b 0.25 was not held. With near-target starts
#: seeds 0 / 1 / 2 tested 0.039 / 0.007 / 0.008 m and hold every ground-effect band
#: (falcon_rl/policies/README.md).
V7_PPO: dict = {"episode_seconds": 30.0, "gamma": 0.995, "eval_every": 100_000,
                "env_options": {"offset_min": 0.0}}

#: The Volantex Ranger's SAC altitude: :data:`HEAVIER_AIRSPEED_PENALTY` as well. On the defaults seed 2
#: held the Ranger 0.3-0.45 m high at 16 m/s, more than 5 % above its 15 m/s trim (0.63 m; 0.56 m after
#: 700 k frames), while seeds 0 / 1 tested 0.054 / 0.019 m; with it, seeds 0 / 1 / 2 tested 0.187 / 0.164
#: / 0.057 m, acquisition 1. On the V7 the weight did not help SAC (seed 1: 0.58 m at 700 k frames), so
#: its SAC keeps 0.5 (:data:`V7_SAC`; falcon_rl/policies/README.md). ``training_defaults`` deep-copies,
#: so the two defaults never share the dict with a run's config.
RANGER_SAC: dict = {"env_options": HEAVIER_AIRSPEED_PENALTY}

#: Training defaults (on top of each recipe's own). PPO: 256 envs x 32 steps per batch (8,192 frames),
#: 20 s episodes, 8 M frames (12 M on the Ranger; the V7: :data:`V7_PPO`); every recipe validates on 16
#: held-out episodes every 500 k frames (SAC, TD3: 50 k) and ships its best snapshot (``keep_best``); SAC
#: and TD3 learn with :data:`OFF_POLICY_CRITIC`, SAC anneals its learning rates, TD3 runs 700 k frames.
#: The Ranger's hold keeps improving past 8 M frames on some seeds and collapses on others (seed 0:
#: 0.030 m at 8.1 M, 0.25 m at 12 M), so the longer run plus the choice holds it to RMSE 0.009-0.025 m
#: over three seeds (0.031-0.112 m from the last weights after 8 M). On the Airship V7, 12 M frames with
#: gamma 0.995 gave 0.056 / 0.106 / 0.009 m on seeds 0 / 1 / 2 (8 M, gamma 0.99: 0.080 / 0.074 / 0.38 m),
#: but its seed 0 no longer held the ground-effect study's lowest band; the V7's PPO trains with
#: :data:`V7_PPO`. Every seed and variant tried, PPO, SAC and TD3, is in falcon_rl/policies/README.md.
SPEC = register_task(TaskSpec(
    name="altitude", task=AltitudeTask, config=AltitudeConfig, gym_id="falcon_rl/Altitude-v0",
    title="Altitude acquisition and hold",
    protocol="falcon_rl.evaluation.protocols:altitude_protocol", metrics=ALTITUDE_METRICS, select_on="rmse_m",
    controllers={"lqr": "falcon_rl.baselines.lqr:AltitudeLQR.from_env",
                 "mppi": "falcon_rl.baselines.mppi:altitude_mppi", "trim": TRIM_HOLD},
    figure="falcon_rl.viz.evaluation:plot_altitude",
    training={"ppo": {"num_envs": 256, "rollout_steps": 32, "frames": 8_000_000, "episode_seconds": 20.0,
                      "reward_scale": 0.1, "eval_every": 500_000, "keep_best": True},
              "sac": {"episode_seconds": 20.0, "eval_every": 50_000, "keep_best": True, **OFF_POLICY_CRITIC,
                      "anneal_lr": True},
              "td3": {"episode_seconds": 20.0, "eval_every": 50_000, "keep_best": True, **OFF_POLICY_CRITIC,
                      "frames": 700_000}},
    airframe_training={"volantex_ranger": {"ppo": {"frames": 12_000_000}, "sac": RANGER_SAC},
                       "airship_v7": {"ppo": V7_PPO, "sac": V7_SAC, "td3": V7_TD3}},
    defaults=TRAINING_ENV_OPTIONS,
))
