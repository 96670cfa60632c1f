"""fdisyn.runtime — everything online: gain files, compiled steps, the Monitor.

This package never imports :mod:`fdisyn.design`; a deployed diagnoser needs
only its gain file and its compiled step (NumPy is the only dependency).
"""
