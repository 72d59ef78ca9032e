"""Inertial navigation: the strapdown mechanization, the φ-angle error-state models and
their sensor blocks, and the one navigation-error definition. Imports :mod:`sinslab.core`;
knows no filter.
"""
