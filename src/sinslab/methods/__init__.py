"""The papers' methods as libraries, with no paper defaults: stationary alignment,
rotation-modulated INS evaluation, transfer alignment, lagged-fix fusion, Schuler
suppression, free-inertial error analysis. Imports core, nav, estimation, fusion;
never files, terminals or the simulator.
"""
