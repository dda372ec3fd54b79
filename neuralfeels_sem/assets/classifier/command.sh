#!/bin/sh
# How assets/classifier/classifier.pt was made (CPU, 2 shared cores).
python run.py task=collect_tactile task.samples_per_class_per_sensor=80
OMP_NUM_THREADS=1 python run.py task=train_classifier classifier.input_size=64 task.lr=1e-3 task.batch_size=16 task.brightness=0.1 task.contrast=0.1 task.color_gain=0.05 task.max_epochs=30 task.patience=6 task.export_fp16=true device=cpu hydra.run.dir=RUN
# stopped for time, then resumed in the same run dir to evaluate and export:
OMP_NUM_THREADS=1 python run.py task=train_classifier classifier.input_size=64 task.lr=1e-3 task.batch_size=16 task.brightness=0.1 task.contrast=0.1 task.color_gain=0.05 task.max_epochs=18 task.patience=6 task.export_fp16=true device=cpu hydra.run.dir=RUN
