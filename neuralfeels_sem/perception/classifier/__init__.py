"""Tactile material classifier: EfficientNet-B0 model, data sets, training, inference."""

from neuralfeels_sem.perception.classifier.infer import SHIPPED_CHECKPOINT, MaterialClassifier
from neuralfeels_sem.perception.classifier.oracle import OracleClassifier

__all__ = ["SHIPPED_CHECKPOINT", "MaterialClassifier", "OracleClassifier"]
