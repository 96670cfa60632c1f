"""Plant models: linear (discrete or continuous), sampled-data, nonlinear (CasADi), exact sampling, and the
reference-problem interface.
"""
