"""The application layer: configuration (pydantic, TOML, ``--set``), run folders,
reports, plotting, user errors and the recorded-data commands. Imports everything below.
"""
