"""MLflow "models from code" entry: the file MLflow copies into a logged inverse mapping.

MLflow runs this file to build the pyfunc model when it is loaded; rigmap
itself never imports it. The model's state comes from its artifacts (see
``rigmap.tracking.pyfunc_model``), not from a pickle.
"""

from pathlib import Path

from mlflow.models import set_model

from rigmap.tracking.pyfunc_model import InverseMappingModel

set_model(InverseMappingModel(Path(__file__).resolve().parent))
