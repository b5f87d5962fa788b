"""The application layer: the only code that reads config (Hydra composition, ``DictConfig``,
``instantiate``). Each module turns a composed config into plain objects and calls the
library, which takes objects and plain values only (``tests/test_app_layer.py``).

- :mod:`~rigmap.app.config`: ``conf/`` found and composed, with the range checks;
- :mod:`~rigmap.app.params`: ``params.yaml`` composed and checked (``rigmap reproduce``);
- :mod:`~rigmap.app.stage`: ``run_stage``, every pipeline script's entry point;
- :mod:`~rigmap.app.placeholders`: a stage command's ``KEY=@NAME`` values;
- :mod:`~rigmap.app.inputs`: the layout, rig and sampler a stage builds;
- :mod:`~rigmap.app.objects`: samplers, regressors and kernels built from ``_target_``;
- :mod:`~rigmap.app.fit`, :mod:`~rigmap.app.evaluate`, :mod:`~rigmap.app.latent`: the fit,
  evaluate and latent jobs;
- :mod:`~rigmap.app.synth`, :mod:`~rigmap.app.edits`: ``rigmap synth`` and ``rigmap edits``;
- :mod:`~rigmap.app.optuna_sweep`: the Hydra callback of the Optuna sweeps.
"""
