"""``hydra/sweeper=optuna``: rigmap's Optuna sweeper (a Hydra plugin, found by Hydra's scan
of the ``hydra_plugins`` namespace package)."""
