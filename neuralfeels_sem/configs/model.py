"""Schema for conf/model/: the semantic neural field (SDF + material branches).

The dataclasses live beside the classes they configure (nerfstudio style) and hold the
only defaults and range checks: SemanticFieldConfig in fields/semantic_field.py,
HashGridConfig in fields/hash_grid.py, SdfHeadConfig and MaterialHeadConfig in
fields/heads.py. The map task builds `SemanticField(config, bound)`, with the bound
computed from the object (not a setting). Re-exported here for callers that build them
by hand (`MaterialHeadConfig(concat_sdf_features=False)`).
"""

from __future__ import annotations

from neuralfeels_sem.fields.hash_grid import HashGridConfig
from neuralfeels_sem.fields.heads import MaterialHeadConfig, SdfHeadConfig
from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig

__all__ = ["HashGridConfig", "MaterialHeadConfig", "SdfHeadConfig", "SemanticFieldConfig"]


def register(cs) -> None:
    cs.store(group="schema/model", name="semantic_sdf", node=SemanticFieldConfig)
