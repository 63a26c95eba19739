"""Simulators (LIBERO / robosuite, Lift, Fetch), the scenes the harness runs, and scripted experts."""
