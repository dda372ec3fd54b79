#!/bin/sh
# How assets/tactile_depth/tactile_depth.pt was made (CPU, one torch thread on a shared
# 2-core machine; renders its own data; real backgrounds from ../shared/data/digit_real/backgrounds).
OMP_NUM_THREADS=1 python run.py task=train_tactile_depth task.export_fp16=true hydra.run.dir=outputs/train_tactile_depth/shipped
cp outputs/train_tactile_depth/shipped/tactile_depth.pt outputs/train_tactile_depth/shipped/report.json outputs/train_tactile_depth/shipped/history.json neuralfeels_sem/assets/tactile_depth/
