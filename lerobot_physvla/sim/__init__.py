"""Simulators and robots the corrector reads state from (LIBERO/robosuite, Lift, Fetch), scripted experts, scenes."""
