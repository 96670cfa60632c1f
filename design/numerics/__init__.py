"""Numerical building blocks: linear algebra, Riccati equations, system norms (frequency sweeps and LMIs),
semidefinite programmes, factorisations.
"""
