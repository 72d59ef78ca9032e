"""Aided navigation: the fusion driver (INS streams + a Kalman filter + measurement
objects + a lag policy), the measurement models, feedback of the estimate into the INS,
the loosely coupled composition and the recorded-data front end.
Imports core, nav, estimation.
"""
