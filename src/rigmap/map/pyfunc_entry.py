"""MLflow "models from code" entry: the file MLflow copies into a saved map model.

MLflow runs this file to build the pyfunc model when it is loaded; rigmap itself never
imports it. The model's state comes from its artifacts (see ``rigmap.map.pyfunc_model``).
"""

from pathlib import Path

from mlflow.models import set_model

from rigmap.map.pyfunc_model import MapClipModel

set_model(MapClipModel(Path(__file__).resolve().parent))
