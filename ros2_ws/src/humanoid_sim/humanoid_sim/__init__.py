"""Simulated humanoid robot: the thesis's humanoid scenario as a workload for efficient_comm.

Will hold the simulation nodes and their sensor and actuator topics; later work fills it in.
"""
