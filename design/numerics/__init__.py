"""Numerical building blocks: linear algebra, Riccati equations, system norms (level set, frequency sweeps and LMIs),
semidefinite programmes, factorisations.
"""
