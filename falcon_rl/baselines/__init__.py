"""Classical baselines (LQR/LQRI, MPPI) as TensorDict policies over the env specs."""
