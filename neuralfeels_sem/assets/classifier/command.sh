#!/bin/sh
# How assets/classifier/classifier.pt was made (CPU, 2 cores, no pretrained weights).
# collect_stage1
python run.py task=collect_tactile dataset.root=data/tactile/sim_v2 task.samples_per_class_per_sensor=80
# stage1 (stopped for time after epoch 10; best.pt kept)
OMP_NUM_THREADS=2 python run.py task=train_classifier dataset.root=data/tactile/sim_v2 classifier.input_size=112 classifier.crop_px=112 task.batch_size=32 task.export_fp16=true classifier.device=cpu task.lr=1e-3 task.max_epochs=40 task.patience=10 hydra.run.dir=RUN1
# collect_stage2
python run.py task=collect_tactile dataset.root=data/tactile/sim_v3 task.samples_per_class_per_sensor=200
# stage2 (stopped after epoch 9, best epoch 6; best.pt kept)
OMP_NUM_THREADS=2 python run.py task=train_classifier dataset.root=data/tactile/sim_v3 classifier.input_size=112 classifier.crop_px=112 task.batch_size=32 task.export_fp16=true classifier.device=cpu classifier.weights=RUN1/best.pt task.lr=1e-3 task.max_epochs=30 task.patience=8 hydra.run.dir=RUN2
# stage3 (early stop after epoch 8, best epoch 4; wrote classifier.pt, report.json)
OMP_NUM_THREADS=2 python run.py task=train_classifier dataset.root=data/tactile/sim_v3 classifier.input_size=112 classifier.crop_px=112 task.batch_size=32 task.export_fp16=true classifier.device=cpu classifier.weights=RUN2/best.pt task.lr=3e-4 task.max_epochs=8 task.patience=4 hydra.run.dir=RUN3
# fresh held-out set
python run.py task=collect_tactile dataset.root=data/tactile/fresh_777 task.samples_per_class_per_sensor=25 seed=777
# fresh evaluation
python run.py task=eval_classifier dataset.root=data/tactile/fresh_777 classifier.checkpoint=neuralfeels_sem/assets/classifier/classifier.pt
# collect_stage4: centred and edge presses (half the presses with a gel border, tilt 15-40 deg), seed 100
python run.py task=collect_tactile dataset.root=data/tactile/sim_v4 task.samples_per_class_per_sensor=300 task.edge_press_fraction=0.5 seed=100
# stage4 (12 epochs from stage 3's classifier.pt; epoch 9's best.pt kept, see manifest.json "selection")
OMP_NUM_THREADS=2 python run.py task=train_classifier dataset.root=data/tactile/sim_v4 classifier.input_size=112 classifier.crop_px=112 task.batch_size=32 task.export_fp16=true classifier.device=cpu classifier.weights=neuralfeels_sem/assets/classifier/classifier.pt task.lr=3e-4 task.max_epochs=12 task.patience=4 hydra.run.dir=RUN4
# held-out sets: fresh edge presses, the rig's own touches (seed 5 picked the epoch; seed 0 = the map runs' frames)
python run.py task=collect_tactile dataset.root=data/tactile/fresh_778_edge task.samples_per_class_per_sensor=25 task.edge_press_fraction=0.5 seed=778
python -m neuralfeels_sem.sim.rig_touches data/tactile/rig_seed5 --seed 5
python -m neuralfeels_sem.sim.rig_touches data/tactile/rig_seed0 --seed 0
python run.py task=eval_classifier dataset.root=data/tactile/rig_seed0
# stage 5 and stage 6 were tried and not shipped (see README.md)
# collect_stage7: the current textures (wood pores, finer metal brushing); centred, edge and feature (rim) presses, seed 300
python run.py task=collect_tactile dataset.root=data/tactile/sim_v6 task.samples_per_class_per_sensor=450 task.edge_press_fraction=0.4 task.feature_press_fraction=0.25 seed=300
# stage7 (24 cosine epochs from stage 4's classifier.pt; the best validation epoch, 21, is what the task exports)
OMP_NUM_THREADS=2 python run.py task=train_classifier dataset.root=data/tactile/sim_v6 classifier.input_size=112 classifier.crop_px=112 task.batch_size=32 task.export_fp16=true classifier.device=cpu classifier.weights=neuralfeels_sem/assets/classifier/classifier.pt task.lr=3e-4 task.lr_schedule=cosine task.max_epochs=24 task.patience=24 seed=0 hydra.run.dir=RUN7
# held-out sets for stage 7: the default sim data set (centred presses), sim_v6's recipe, the rig's own touches
python run.py task=collect_tactile dataset.root=data/tactile/fresh_centred_779 task.samples_per_class_per_sensor=100 seed=779
python run.py task=collect_tactile dataset.root=data/tactile/fresh_mixed_778 task.samples_per_class_per_sensor=100 task.edge_press_fraction=0.4 task.feature_press_fraction=0.25 seed=778
python -m neuralfeels_sem.sim.rig_touches data/tactile/rig_seed0 --seed 0
python -m neuralfeels_sem.sim.rig_touches data/tactile/rig_seed5 --seed 5
# report.json: the test split (split.json "test") copied to a folder with its manifest entries, then
python run.py task=eval_classifier dataset.root=data/tactile/sim_v6_test
# held_out_fresh_mixed_781.json: a fresh collection with sim_v6's recipe (per-image kind of press and surface curvature in its manifest), judged by the shipped checkpoint
python run.py task=collect_tactile task.root=data/tactile/fresh_mixed_781 task.samples_per_class_per_sensor=100 task.edge_press_fraction=0.4 task.feature_press_fraction=0.25 seed=781
python run.py task=eval_classifier dataset.root=data/tactile/fresh_mixed_781
# collect_stage8: the rig's own touches of generated development objects 20-59 at rig seed 3 (300 frames each),
# edge imprints (edge share > 0.5) kept on every 4th frame and other touches on every 10th (4530 images; as run, the
# full set was written to data/tactile/rig_gen20_59_s3 and thinned by this rule afterwards), and simulated presses to mix in
python -m neuralfeels_sem.bench.rig_touches data/tactile/rig_gen_sub --seed 3 --generated 20-59 --frames 300 --keep-every 4 10
python run.py task=collect_tactile dataset.root=data/tactile/sim_mix301 task.samples_per_class_per_sensor=150 task.edge_press_fraction=0.4 task.feature_press_fraction=0.25 seed=301
# stage8 (5 cosine epochs from stage 7's classifier.pt, the shipped one then; each epoch draws as many simulated presses as rig touches; wrote classifier.pt, report.json on the rig touches' test split)
OMP_NUM_THREADS=2 python run.py task=train_classifier dataset.root=data/tactile/rig_gen_sub dataset.sim_root=data/tactile/sim_mix301 task.init_from=shipped task.real_ratio=0.5 task.lr=1e-4 task.lr_schedule=cosine task.max_epochs=5 task.patience=5 task.export_fp16=true classifier.device=cpu seed=0 hydra.run.dir=RUN8
# held_out_sim_v6_test.json: stage 7's test split (recollected with stage 7's command above, the same images), copied with its manifest entries into a folder
python run.py task=eval_classifier dataset.root=data/tactile/sim_v6_test
# held_out_fresh_mixed_781.json: the fresh collection above (seed 781), judged by stage 8's checkpoint
python run.py task=eval_classifier dataset.root=data/tactile/fresh_mixed_781
# collect_stage9: round 6's rig touches (the same 4530, same seed and rule) plus, on every 2nd frame, the patch crops of
# imprints that straddle materials (not edge imprints), each labelled with the material under its centre (7877 crops)
python -m neuralfeels_sem.bench.rig_touches data/tactile/rig_gen_mixp --seed 3 --generated 20-59 --frames 300 --keep-every 4 10 --mixed-patches 2
# stage9 (4 cosine epochs from stage 8's classifier.pt, the shipped one then; rig images mixed 1:1 with sim_mix301; wrote classifier.pt, report.json on the rig images' test split)
OMP_NUM_THREADS=2 python run.py task=train_classifier dataset.root=data/tactile/rig_gen_mixp dataset.sim_root=data/tactile/sim_mix301 task.init_from=shipped task.real_ratio=0.5 task.lr=1e-4 task.lr_schedule=cosine task.max_epochs=4 task.patience=4 task.export_fp16=true classifier.device=cpu seed=0 hydra.run.dir=RUN9
# held-out, judged by stage 9's checkpoint (rewriting held_out_sim_v6_test.json and held_out_fresh_mixed_781.json): stage 7's test split
# and the fresh collection (as above), and, new, the patch crops of the nine map-development objects' mixed imprints at mapping seed 0
# (held_out_rig_dev9_mixed_patches.json)
python run.py task=eval_classifier dataset.root=data/tactile/sim_v6_test
python run.py task=eval_classifier dataset.root=data/tactile/fresh_mixed_781
python -m neuralfeels_sem.bench.rig_touches data/tactile/rig_dev9_mixp_s0 --seed 0 --objects random_1 random_2 random_3 random_6 random_8 random_13 random_15 random_16 random_19 --frames 300 --keep-every 100000 100000 --mixed-patches 1
python run.py task=eval_classifier dataset.root=data/tactile/rig_dev9_mixp_s0
