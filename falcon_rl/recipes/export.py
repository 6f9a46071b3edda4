"""Deprecated home of the policy file format, kept for old imports: use :mod:`falcon_rl.policies`."""

from __future__ import annotations

from ..policies.format import (
    FORMAT,
    DeployedPolicy,
    export_torchscript,
    load_policy,
    policy_document,
    read_policy,
    save_policy,
)

__all__ = ["FORMAT", "DeployedPolicy", "export_torchscript", "load_policy", "policy_document", "read_policy",
           "save_policy"]
