"""Subcommands of the falcon-rl CLI, discovered by name (see falcon_rl/cli.py)."""
