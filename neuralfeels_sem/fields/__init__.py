"""Neural fields: hash-grid and spherical-harmonics encodings, heads, SemanticField, optimiser."""

from neuralfeels_sem.fields.hash_grid import HashGridEncoding
from neuralfeels_sem.fields.optim import FieldAdam
from neuralfeels_sem.fields.semantic_field import SemanticField, evaluate_chunked
from neuralfeels_sem.fields.spherical_harmonics import (
    SphericalHarmonicsEncoding,
    spherical_harmonics,
)

__all__ = [
    "FieldAdam",
    "HashGridEncoding",
    "SemanticField",
    "SphericalHarmonicsEncoding",
    "evaluate_chunked",
    "spherical_harmonics",
]
