"""Evaluation: built diagnosers, the Monte Carlo through their compiled steps (on the Python simulators or fused
with a sample model in one C campaign) and the detection metrics.
"""
