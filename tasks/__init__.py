"""Thin Prefect tasks, one per stage: resolve refs -> load -> call ``multithumbs`` -> write -> return a ref."""
