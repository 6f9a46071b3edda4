"""Cross-validation against other simulators (JSBSim export and trajectory comparison)."""
