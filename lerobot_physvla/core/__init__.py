"""The algorithm: configuration, physical state, phase FSM (Branch A), Euler-Lagrange gate (Branch B), corrector.

Imports only numpy, numba and mujoco (never lerobot, torch, robosuite, libero or gymnasium).
"""
