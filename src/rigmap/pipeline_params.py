"""``python -m rigmap.pipeline_params check|fresh``: the command dvc.yaml's ``check_params``
stage and CI run, kept at this name so the pipeline's commands do not change; the work is
:mod:`rigmap.app.params`."""

from rigmap.app.params import main

if __name__ == "__main__":
    raise SystemExit(main())
