"""Whether a run used the shipped networks' weights of today, read from its commit.

`classifier.checkpoint=null` and `mapping.mapper.tactile_depth.checkpoint=null` load the
networks shipped in the repository, so a run's config says "the shipped one" whichever
weights shipped when it ran. A run records its commit (`metrics.json` `code.commit`), and
git knows the shipped file's blob at that commit: where it differs from today's file, the
run did not measure today's defaults, and the results page shows it with that key set to
`shipped@<blob>` (the blob's first 7 hex digits), as for any other changed default. A run
without a commit, or whose commit the repository lacks, is taken at its config's word.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import Any

from neuralfeels_sem.perception.classifier.infer import SHIPPED_CHECKPOINT as CLASSIFIER
from neuralfeels_sem.perception.tactile_depth_net.predict import SHIPPED_CHECKPOINT as DEPTH
from neuralfeels_sem.utils.code_version import git_output
from neuralfeels_sem.utils.paths import REPO_DIR

# The config key that picks each network's weights (null: shipped) and its shipped file.
SHIPPED: dict[str, str] = {
    "classifier.checkpoint": CLASSIFIER.relative_to(REPO_DIR).as_posix(),
    "mapping.mapper.tactile_depth.checkpoint": DEPTH.relative_to(REPO_DIR).as_posix(),
}
SHORT = 7  # hex digits of a blob shown, as git abbreviates


@cache
def blob_at(commit: str, path: str, repo: Path = REPO_DIR) -> str | None:
    """The blob id of `path` at `commit` (None: no such commit or file here)."""
    return git_output("rev-parse", "--verify", "--quiet", f"{commit}:{path}", repo=repo) or None


@cache
def blob_today(path: str, repo: Path = REPO_DIR) -> str | None:
    """The blob id of the file as it is in the working tree (None: absent)."""
    if not (repo / path).is_file():
        return None
    return git_output("hash-object", "--", path, repo=repo) or None


def weights_drift(
    flat_config: dict[str, Any],
    overrides: dict[str, str],
    commit: str | None,
    repo: Path = REPO_DIR,
) -> dict[str, tuple[str, str]]:
    """{key: (the run's shipped weights, today's)} for each shipped network the run loaded
    (its key null and not overridden) whose file differs between the run's commit and today."""
    if not commit:
        return {}
    out = {}
    for key, path in SHIPPED.items():
        if key in overrides or flat_config.get(key) is not None:
            continue
        then, now = blob_at(commit, path, repo), blob_today(path, repo)
        if then is not None and now is not None and then != now:
            out[key] = (f"shipped@{then[:SHORT]}", f"shipped@{now[:SHORT]}")
    return out
