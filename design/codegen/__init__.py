"""Export: the step function of a gain file (one CasADi Function per diagnoser) and its C library.
"""
