"""SemanticFeels entry point: compose the config tree, then run the chosen task.

python run.py sensor=sim object=plushie          # default task: map
python run.py task=train_classifier dataset.root=PATH
python run.py -m experiment=multi_material launcher=joblib
"""

import hydra
from omegaconf import DictConfig

import neuralfeels_sem  # noqa: F401  (sets headless rendering defaults before any GL import)
from neuralfeels_sem.configs import register_configs

register_configs()


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
def main(cfg: DictConfig) -> float | None:
    from neuralfeels_sem.tasks.runner import run_task

    return run_task(cfg)


if __name__ == "__main__":
    main()
