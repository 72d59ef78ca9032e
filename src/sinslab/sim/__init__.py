"""Simulation: the trajectory motion language and its synthesis kernels, indexing
(rotate-stop) mechanisms, the IMU error model and its random streams, Allan analysis.
Imports :mod:`sinslab.core`.
"""
