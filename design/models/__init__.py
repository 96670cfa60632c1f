"""Plant models: linear (discrete or continuous), sampled-data, nonlinear (CasADi, with its expression language and
its operation lists), exact sampling.
"""
