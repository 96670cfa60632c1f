"""Simulation, Monte Carlo evaluation and detection metrics.
"""
