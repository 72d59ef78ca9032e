"""Estimation independent of any INS: Kalman predict/update/discretisation, compiled
linear-system loops (covariance analysis, error budgets), the stepped filter with its
history, observability and Monte Carlo campaigns. Imports :mod:`sinslab.core` only.
"""
