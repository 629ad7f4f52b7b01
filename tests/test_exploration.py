"""Tests for TD3ExplorationPolicy (modules/exploration.py): the same action as TorchRL's sequence."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.data import Bounded
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import MLP, AdditiveGaussianModule, TanhModule

from torchrl_sail import TD3ExplorationPolicy

OBS, ACT = 4, 2


def make_actor(spec, in_keys=("observation",)):
    return TensorDictSequential(
        TensorDictModule(MLP(in_features=OBS, out_features=ACT, num_cells=[16]), list(in_keys), ["param"]),
        TanhModule(["param"], ["action"], spec=spec),
    )


def observations(n=8, seed=0):
    return TensorDict({"observation": 3 * torch.randn(n, OBS, generator=torch.Generator().manual_seed(seed))}, [n])


SPECS = {
    "unit": Bounded(-1.0, 1.0, (ACT,)),
    "asymmetric": Bounded(torch.tensor([-2.0, 0.0]), torch.tensor([0.5, 3.0]), (ACT,)),
}


@pytest.mark.parametrize("spec", SPECS.values(), ids=SPECS.keys())
@pytest.mark.parametrize("mode", [None, ExplorationType.RANDOM, ExplorationType.DETERMINISTIC])
def test_equals_torchrls_sequence(spec, mode):
    torch.manual_seed(0)
    actor = make_actor(spec)
    # sigma 2 x std 0.5: large enough that some actions leave the box and are projected back
    noise = AdditiveGaussianModule(spec=spec, sigma_init=2.0, sigma_end=2.0, std=0.5)
    sequence, fused = TensorDictSequential(actor, noise), TD3ExplorationPolicy(actor, noise)
    with set_exploration_type(mode) if mode is not None else torch.no_grad():
        torch.manual_seed(1)
        expected = sequence(observations())["action"]
        torch.manual_seed(1)
        out = fused(observations())
    assert torch.equal(out["action"], expected)
    assert "param" not in out.keys()  # the action only
    if mode is ExplorationType.DETERMINISTIC:
        assert torch.equal(expected, actor(observations())["action"])  # no noise
    else:
        clipped = (expected == spec.space.low) | (expected == spec.space.high)
        assert clipped.any() and not clipped.all()


def test_without_noise_is_the_actor():
    actor = make_actor(SPECS["asymmetric"])
    assert torch.equal(TD3ExplorationPolicy(actor)(observations())["action"], actor(observations())["action"])


def test_sees_optimizer_steps_and_annealing():
    spec = SPECS["unit"]
    actor = make_actor(spec)
    noise = AdditiveGaussianModule(spec=spec, sigma_init=1.0, sigma_end=0.0, annealing_num_steps=2, std=0.3)
    fused = TD3ExplorationPolicy(actor, noise)
    with torch.no_grad():
        for p in actor.parameters():
            p.add_(0.5)
    noise.step(2)  # sigma 1 -> 0: no noise left
    assert torch.equal(fused(observations())["action"], actor(observations())["action"])
    # the modules are the policy's own: TensorDict.from_module (weight sync to workers) reaches them
    params = TensorDict.from_module(fused)
    assert params["mlp", "0", "weight"] is actor.module[0].module[0].weight


def test_reads_every_in_key_as_the_mlp_does():
    spec = SPECS["unit"]
    actor = TensorDictSequential(
        TensorDictModule(MLP(in_features=OBS, out_features=ACT, num_cells=[8]), ["a", "b"], ["param"]),
        TanhModule(["param"], ["action"], spec=spec),
    )
    data = TensorDict({"a": torch.randn(5, 1), "b": torch.randn(5, OBS - 1)}, [5])
    assert torch.equal(TD3ExplorationPolicy(actor)(data.clone())["action"], actor(data.clone())["action"])


def test_refuses_other_structures():
    spec = SPECS["unit"]
    actor = make_actor(spec)
    with pytest.raises(TypeError, match="TensorDictSequential\\(TensorDictModule\\(MLP\\), TanhModule\\)"):
        TD3ExplorationPolicy(actor.module[0])
    rewired = TensorDictSequential(actor.module[0], TanhModule(in_keys=["other"], out_keys=["action"], spec=spec))
    with pytest.raises(TypeError, match="map the MLP's output to one action"):
        TD3ExplorationPolicy(rewired)
    # supports says the same without building one
    assert TD3ExplorationPolicy.supports(actor)
    assert not TD3ExplorationPolicy.supports(actor.module[0]) and not TD3ExplorationPolicy.supports(rewired)
    with pytest.raises(TypeError, match="noise must be an AdditiveGaussianModule"):
        TD3ExplorationPolicy(actor, torch.nn.Identity())
    other = AdditiveGaussianModule(spec=spec, action_key="other")
    with pytest.raises(ValueError, match="perturbs 'other', the actor writes 'action'"):
        TD3ExplorationPolicy(actor, other)
    with pytest.raises(ValueError, match="has no spec"):
        TD3ExplorationPolicy(actor, AdditiveGaussianModule())
