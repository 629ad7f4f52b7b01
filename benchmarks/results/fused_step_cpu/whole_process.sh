#!/bin/bash
# whole-process: fused vs loss TD3 step, Hopper paper teacher, 1 thread, alternating, 2 rounds
cd /work/refac; T=/work/shared/data/teachers; H=$T/expert_data_no_img_Hopper_scores_1500_episodes_1.npz
export OMP_NUM_THREADS=1 WANDB_SILENT=true PYTHONPATH=/work/refac
for r in 1 2; do for impl in fused loss; do
  d=/work/bench_whole/$impl-$r; rm -rf $d
  /usr/bin/time -f "%e" -o $d.time /work/main/.venv/bin/python examples/sail_td3.py hydra.run.dir=$d env=Hopper-v4 teacher.path=$H seed=0 threads=1 \
    collector.total_frames=8000 collector.init_random_frames=3000 eval.every_frames=8000 eval.episodes=1 logger.backends=[csv] \
    checkpoint.every_frames=0 eval.best_policy.episodes=1 optim.implementation=$impl > /dev/null 2>&1
  python3 -c "import json;s=json.load(open('$d/summary.json'));print('$impl', $r, 'wall', open('$d.time').read().strip(), 'train_fps', round(s['train_frames_per_second'],1), 'update_s', round(s['time_seconds'].get('update',0),1), 'final', round(s['final_eval_return'],1))"
done; done
