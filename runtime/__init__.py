"""fdisyn.runtime — everything online: gain files, compiled steps, the Monitor.

This package never imports the rest of :mod:`fdisyn` (the design side); a deployed diagnoser needs
only its gain file and its compiled step (NumPy is the only dependency).
"""
