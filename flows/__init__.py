"""Prefect flows: the synthetic demo through the real stages (more flows: DESIGN §6)."""
