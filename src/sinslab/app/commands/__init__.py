"""The recorded-data commands of the CLI (``navigate``, ``allan``, ``align``); each module
defines ``register(app)``."""
