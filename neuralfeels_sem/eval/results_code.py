"""Whether a run ran today's code where its behaviour changed without a config key.

Most changes of what a run measures come with a config key (results_drift.py reads them),
the shipped networks' weights with their file (results_weights.py). A fix in the simulated
rig changes every simulated run's figures with no key to tell the runs before it apart. Such
changes are listed here with the commit that made them; a run whose recorded commit
(`metrics.json` `code.commit`) does not contain that commit shows, on the results page, the
change's key set to `before@<commit>` (today's: `since@<commit>`), as for any other changed
default. A run without a commit, or whose commit the repository lacks, is taken as today's.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import Any, NamedTuple

from neuralfeels_sem.utils.code_version import git_output
from neuralfeels_sem.utils.paths import REPO_DIR

SHORT = 7  # hex digits of a commit shown, as git abbreviates


class BehaviourChange(NamedTuple):
    commit: str  # the commit that changed the behaviour (40 hex digits)
    sensor: str  # the sensor whose runs it changes (config sensor.name)
    what: str  # what changed, as the results page says it


BEHAVIOUR_CHANGES: dict[str, BehaviourChange] = {
    "sim.rig": BehaviourChange(
        commit="bebc0c69274aea2fed0ab7a5257243fb508a3b84",
        sensor="sim",
        what="no finger ends a step inside the object deeper than a gel can be pressed",
    ),
}


@cache
def contains(commit: str, change: str, repo: Path = REPO_DIR) -> bool | None:
    """Whether `commit` has `change` in its history (None: either is unknown here)."""
    for c in (commit, change):
        if git_output("rev-parse", "--verify", "--quiet", f"{c}^{{commit}}", repo=repo) is None:
            return None
    return git_output("merge-base", "--is-ancestor", change, commit, repo=repo) is not None


def code_drift(
    flat_config: dict[str, Any], commit: str | None, repo: Path = REPO_DIR
) -> dict[str, tuple[str, str]]:
    """{key: (the run's code, today's)} for each behaviour change the run's commit lacks."""
    if not commit:
        return {}
    out = {}
    for key, change in BEHAVIOUR_CHANGES.items():
        if flat_config.get("sensor.name") != change.sensor:
            continue
        if contains(commit, change.commit, repo) is False:
            short = change.commit[:SHORT]
            out[key] = (f"before@{short}", f"since@{short}")
    return out
