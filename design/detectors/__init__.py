"""Residual evaluation: each detector's statistic and its threshold from the statistic's law (χ², WSSR, CUSUM, GLR).
"""
