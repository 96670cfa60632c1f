"""Simulation: the plants' runs from one description of each input signal and fault kind, the reference problems'
interface (:class:`Problem`, :class:`Scenario`, :class:`Batch`) and the plant files that describe a user's own."""
