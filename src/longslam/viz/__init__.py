"""Plots shared by the CLI, the demo and the study report."""
