"""Residual evaluators and their thresholds from the statistics' laws (χ², WSSR).
"""
