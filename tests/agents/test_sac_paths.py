"""SAC run the fast way against the reference way: same update, same buffer rows, same runs,
and checkpoints that either path resumes."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from seqrank.agents.sac import SAC, Execution, SACSettings
from seqrank.agents.sac.critics import canonical_weights, load_canonical_weights
from seqrank.agents.sac.precision import matmul_precision
from seqrank.buffer import Batch, ReplayBuffer
from seqrank.config import resolve_config
from seqrank.reward.model import RewardModel
from seqrank.training.runs import RunDir
from seqrank.training.runtime import resolve_runtime
from seqrank.training.trainer import Trainer
from support.runs import resume_after_kill, run, tiny_config, without_timing

CPU = torch.device("cpu")
SETTINGS = SACSettings(
    hidden=64,
    layers=2,
    actor_lr=5e-4,
    critic_lr=5e-4,
    alpha_lr=1e-4,
    init_temperature=0.1,
    discount=0.99,
    tau=0.005,
    target_update_every=2,
)
OBS, ACT, ROWS = 7, 3, 48
CUDA = pytest.mark.gpu


FLAT = pytest.mark.parametrize("flat", [False, True], ids=["autograd", "flat"])


def fast_execution(precision: str = "fp32", flat: bool = False) -> Execution:
    """The fast path's way to run the update, without CUDA graphs; `flat`: the CPU's flat
    update (`agents.flat_update`), else autograd's (as on CUDA)."""
    return Execution(stacked_critics=True, fused_adam=True, precision=precision, flat=flat)


def twins(
    precision: str = "fp32", device: torch.device = CPU, flat: bool = False
) -> tuple[SAC, SAC]:
    """A reference agent and a fast one holding the same weights."""
    torch.manual_seed(0)
    reference = SAC(OBS, ACT, SETTINGS, device)
    fast = SAC(OBS, ACT, SETTINGS, device, fast_execution(precision, flat))
    fast.actor.load_state_dict(reference.actor.state_dict())
    load_canonical_weights(fast.critic, canonical_weights(reference.critic))
    load_canonical_weights(fast.critic_target, canonical_weights(reference.critic_target))
    return reference, fast


def random_batch(generator: torch.Generator, device: torch.device = CPU) -> Batch:
    def draw(*shape: int) -> torch.Tensor:
        return torch.randn(shape, generator=generator).to(device)

    not_done = (torch.rand((ROWS, 1), generator=generator) > 0.1).float().to(device)
    return Batch(draw(ROWS, OBS), draw(ROWS, ACT).tanh(), draw(ROWS, 1), draw(ROWS, OBS), not_done)


def all_changed(before: object, after: object) -> bool:
    return all(not torch.equal(a, b) for a, b in zip(before, after, strict=True))  # type: ignore[call-overload]


def stacked(reference: SAC, fast: SAC, which: str) -> list[torch.Tensor]:
    """The reference's twin critic (or target) in the fast layout."""
    return fast.critic.from_canonical(canonical_weights(getattr(reference, which)))


def assert_same_agents(reference: SAC, fast: SAC, atol: float) -> None:
    pairs = [
        (list(reference.actor.parameters()), list(fast.actor.parameters())),
        (stacked(reference, fast, "critic"), list(fast.critic.parameters())),
        (stacked(reference, fast, "critic_target"), list(fast.critic_target.parameters())),
        ([reference.log_alpha], [fast.log_alpha]),
    ]
    for expected, actual in pairs:
        for a, b in zip(expected, actual, strict=True):
            torch.testing.assert_close(b.detach().cpu(), a.detach().cpu(), atol=atol, rtol=0)


def test_stacked_critic_gives_the_reference_q_values():
    reference, fast = twins()
    batch = random_batch(torch.Generator().manual_seed(1))
    expected = reference.critic(batch.obs, batch.action)
    actual = fast.critic(batch.obs, batch.action)
    for a, b in zip(expected, actual, strict=True):
        torch.testing.assert_close(b, a, atol=1e-6, rtol=1e-6)


@FLAT
def test_fp32_updates_match_the_reference_from_the_same_state_and_batch(flat):
    reference, fast = twins(flat=flat)
    generator = torch.Generator().manual_seed(1)
    moved = copy.deepcopy(reference.actor.state_dict())
    for _ in range(6):  # three soft target updates among them
        batch = random_batch(generator)
        next_noise = torch.randn((ROWS, ACT), generator=generator)
        noise = torch.randn((ROWS, ACT), generator=generator)
        reference.update_with_noise(batch, next_noise, noise)
        fast.update_with_noise(batch, next_noise, noise)
        expected, actual = reference.last_metrics, fast.last_metrics
        for name, value in expected.items():
            assert actual[name] == pytest.approx(value, rel=1e-5, abs=1e-7), name
    assert fast.updates == reference.updates == 6
    assert_same_agents(reference, fast, atol=1e-6)
    assert all_changed(moved.values(), fast.actor.parameters())  # not untouched weights


@pytest.mark.parametrize(
    ("precision", "device", "flat"),
    [
        ("bf16", CPU, False),
        ("bf16", CPU, True),
        pytest.param("bf16", torch.device("cuda"), False, marks=CUDA),
        pytest.param("tf32", torch.device("cuda"), False, marks=CUDA),
    ],
)
def test_reduced_precision_stays_within_its_documented_tolerance(precision, device, flat):
    """bf16 and TF32 (docs/guides/speed.md): losses within 1%, the parameter steps pointing the
    same way (cosine similarity at least 0.98)."""
    reference, fast = twins(precision, device, flat)
    before = [p.detach().clone() for p in reference.actor.parameters()]
    generator = torch.Generator().manual_seed(1)
    batch = random_batch(generator, device)
    next_noise = torch.randn((ROWS, ACT), generator=generator).to(device)
    noise = torch.randn((ROWS, ACT), generator=generator).to(device)
    with matmul_precision("fp32"):
        reference.update_with_noise(batch, next_noise, noise)
    expected = reference.last_metrics
    fast.update_with_noise(batch, next_noise, noise)
    for name, value in fast.last_metrics.items():
        assert value == pytest.approx(expected[name], rel=1e-2), name

    def step(params: object) -> torch.Tensor:
        return torch.cat([(p.detach() - b).flatten() for p, b in zip(params, before, strict=True)])  # type: ignore[call-overload]

    cosine = torch.nn.functional.cosine_similarity(
        step(reference.actor.parameters()), step(fast.actor.parameters()), dim=0
    )
    assert cosine >= 0.98


@FLAT
def test_critic_reset_happens_in_place(flat):
    _, fast = twins(flat=flat)
    fast.update(random_batch(torch.Generator().manual_seed(1)), torch.Generator())
    addresses = [p.data_ptr() for p in fast.critic.parameters()]
    old = [p.detach().clone() for p in fast.critic.parameters()]
    fast.reset_critic()
    assert [p.data_ptr() for p in fast.critic.parameters()] == addresses
    assert all_changed(old, fast.critic.parameters())
    for a, b in zip(fast.critic.parameters(), fast.critic_target.parameters(), strict=True):
        assert torch.equal(a, b)
    for state in fast.critic_opt.state.values():
        assert all(float(v.abs().sum()) == 0 for v in state.values())


@FLAT
def test_the_capture_warm_up_is_undone_completely(flat):
    """Before a CUDA graph is captured, warm-up updates run and are then rolled back: the
    tensors the graph wrapper restores must be every tensor an update changes (checked
    here on the CPU)."""
    _, fast = twins(flat=flat)
    generator = torch.Generator().manual_seed(1)
    fast.update(random_batch(generator), generator)  # the optimisers' state exists
    saved = [(t, t.detach().clone()) for t in fast._touched()]
    before = copy.deepcopy(fast.state_dict())
    for _ in range(4):  # two of them also move the target critics
        fast.update(random_batch(generator), generator)
    with torch.no_grad():
        for tensor, copied in saved:
            tensor.copy_(copied)
    fast.updates = before["updates"]
    assert_same_state(fast.state_dict(), before)


def assert_same_state(actual: object, expected: object, where: str = "") -> None:
    """Nested checkpoint states hold equal tensors and values."""
    if isinstance(expected, dict):
        assert isinstance(actual, dict) and actual.keys() == expected.keys(), where
        for key, value in expected.items():
            assert_same_state(actual[key], value, f"{where}/{key}")
    elif isinstance(expected, torch.Tensor):
        assert isinstance(actual, torch.Tensor) and torch.equal(actual, expected), where
    else:
        assert actual == expected, where


@FLAT
def test_a_checkpoint_moves_between_the_reference_and_fast_layouts(flat):
    """Weights, temperature and Adam state saved by one path load into the other and save
    back unchanged; the loaded agents compute the same Q-values."""
    reference, fast = twins(flat=flat)
    generator = torch.Generator().manual_seed(3)
    for _ in range(3):
        fast.update(random_batch(generator), generator)
    saved = copy.deepcopy(fast.state_dict())
    reference.load_state_dict(saved)
    assert_same_state(reference.state_dict(), saved)
    back = SAC(OBS, ACT, SETTINGS, CPU, fast_execution(flat=flat))
    back.load_state_dict(reference.state_dict())
    assert_same_state(back.state_dict(), saved)
    batch = random_batch(generator)
    for a, b in zip(
        reference.critic(batch.obs, batch.action), fast.critic(batch.obs, batch.action), strict=True
    ):
        torch.testing.assert_close(a, b, atol=1e-6, rtol=1e-6)


def test_an_old_path_specific_checkpoint_is_refused_by_name():
    reference, _ = twins()
    old = {k: v for k, v in reference.state_dict().items() if k != "layout"}
    with pytest.raises(ValueError, match="saved by an older seqrank"):
        reference.load_state_dict(old)


def test_staged_adds_write_the_rows_and_learned_rewards_of_plain_adds():
    plain, staged = ReplayBuffer(6, 2, 1, CPU), ReplayBuffer(6, 2, 1, CPU)

    def reward_fn(obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return obs[:, :1] * 10 + action

    for i in range(9):  # wraps
        obs, action, next_obs = np.full(2, i, np.float32), np.full(1, -i, np.float32), np.ones(2)
        learned = float(reward_fn(torch.tensor(obs)[None], torch.tensor(action)[None]))
        plain.add(obs, action, 0.5 * i, learned, next_obs, i == 4)
        staged.add_transition(obs, action, 0.5 * i, next_obs, i == 4, reward_fn)
    assert torch.equal(staged.table, plain.table)
    assert staged.index == plain.index == 3 and len(staged) == 6
    assert float(staged.size_t) == 6


def test_device_sampling_draws_only_stored_rows():
    buffer = ReplayBuffer(100, 1, 1, CPU)
    for i in range(5):
        buffer.add(np.full(1, i + 1, np.float32), np.zeros(1), 0.0, 0.0, np.zeros(1), False)
    torch.manual_seed(0)
    drawn = buffer.sample_on_device(4000).obs[:, 0]
    assert set(drawn.tolist()) == {1.0, 2.0, 3.0, 4.0, 5.0}  # never an empty row (0)


def test_reward_training_reads_back_once_per_epoch_with_the_same_result():
    from support.runs import segment_pairs

    results = []
    for sync in (True, False):
        torch.manual_seed(0)
        model = RewardModel(3, 3, 32, 2, 3e-3, CPU)
        segments, first, second, labels = segment_pairs(100)
        gen = torch.Generator().manual_seed(1)
        result = model.train(segments, first, second, labels, 8, 32, 0.999, gen, sync)
        results.append((result, [p.detach().clone() for p in model.net.parameters()]))
    (a, weights_a), (b, weights_b) = results
    assert a.epochs == b.epochs == 8 and a.accuracy == b.accuracy
    assert a.loss == pytest.approx(b.loss, rel=1e-6)
    assert all(torch.equal(x, y) for x, y in zip(weights_a, weights_b, strict=True))


@pytest.fixture(scope="module")
def fast_run(tmp_path_factory):
    return run(tmp_path_factory.mktemp("fast") / "full", tiny_config(path="fast"))


def test_a_fast_run_goes_through_every_phase(fast_run):
    rows = fast_run.run_dir.read_metrics()
    assert fast_run.agent.execution.stacked_critics and fast_run.runtime.precision == "fp32"
    assert [r["step"] for r in rows if r["kind"] == "feedback"] == [1200, 1700, 2200]
    assert [r["step"] for r in rows if r["kind"] == "eval"] == [1600, 3200]
    assert fast_run.agent.updates >= 3200 - 300
    assert fast_run.replay.storage == CPU  # on a GPU it would be the device
    train_rows = [r for r in rows if r["kind"] == "train"]
    assert train_rows and all(np.isfinite(r["critic_loss"]) for r in train_rows)
    # the learned rewards of the buffer are those of the final reward model
    n = len(fast_run.replay)
    with torch.no_grad():
        expected = fast_run.reward_model.reward(fast_run.replay.obs[:n], fast_run.replay.action[:n])
    torch.testing.assert_close(fast_run.replay.reward[:n], expected)


def test_a_resumed_fast_run_ends_with_the_same_numbers(fast_run, tmp_path):
    resumed, state = resume_after_kill(tmp_path, tiny_config(path="fast"))
    assert state["next_action"] is not None  # the action computed ahead is kept
    # the step-1600 evaluation was still running in the background at the checkpoint
    assert [p["step"] for p in state["pending_evaluations"]] == [1600]
    rows = without_timing(resumed.run_dir.read_metrics())
    assert rows == without_timing(fast_run.run_dir.read_metrics())
    resumed_actor, finished_actor = resumed.agent.actor, fast_run.agent.actor
    for a, b in zip(resumed_actor.parameters(), finished_actor.parameters(), strict=True):
        assert torch.equal(a, b)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (dict(path="quick"), "unknown path 'quick'; accepted: auto, reference, fast"),
        (dict(precision="fp16"), "unknown precision 'fp16'; accepted: auto, fp32, tf32, bf16"),
        (dict(path="reference", precision="bf16"), "precision 'bf16' needs the fast path"),
    ],
)
def test_bad_path_and_precision_are_named(overrides, message):
    with pytest.raises(ValueError, match=message):
        tiny_config(**overrides)


def test_fast_path_is_refused_for_the_dqn_task():
    with pytest.raises(ValueError, match="block:place learns with DQN"):
        resolve_config("block:place", "small", dict(path="fast"))


def test_path_and_precision_resolution():
    cuda = torch.device("cuda")
    assert resolve_runtime(cuda, "auto", "auto", discrete=False).precision == "tf32"
    assert resolve_runtime(cuda, "auto", "auto", discrete=False).fast
    assert not resolve_runtime(cuda, "auto", "auto", discrete=True).fast  # DQN
    assert resolve_runtime(cuda, "reference", "auto", discrete=False).precision == "fp32"
    assert resolve_runtime(CPU, "fast", "auto", discrete=False).precision == "fp32"
    assert resolve_runtime(CPU, "fast", "bf16", discrete=False).precision == "bf16"
    assert not resolve_runtime(CPU, "auto", "auto", discrete=False).fast
    with pytest.raises(ValueError, match="the reference path is strict fp32"):
        resolve_runtime(CPU, "auto", "tf32", discrete=False)  # auto on a CPU: reference


@CUDA
def test_graph_updates_on_cuda_train_the_critic():
    """The captured update restores what its warm-up changed, then trains the critic."""
    device = torch.device("cuda")
    torch.manual_seed(0)
    agent = SAC(OBS, ACT, SETTINGS, device, Execution.fast(device, "fp32"))
    buffer = ReplayBuffer(1000, OBS, ACT, device)
    generator = torch.Generator().manual_seed(0)
    for _ in range(500):  # reward = first observation feature, learnable by the critic
        obs = torch.randn(OBS, generator=generator).numpy()
        buffer.add(obs, np.zeros(ACT, np.float32), 0.0, float(obs[0]), obs, False)
    agent.update(buffer.sample(ROWS, generator), generator)  # the optimisers' state exists
    before = [p.detach().clone() for p in agent.actor.parameters()]
    agent.update_from(buffer, ROWS, generator)  # captures, then replays once
    assert agent.capture_seconds > 0 and agent.updates == 2
    assert all_changed(before, agent.actor.parameters())
    first = agent.last_metrics["critic_loss"]
    for _ in range(300):
        agent.update_from(buffer, ROWS, generator)
    assert agent.updates == 302
    assert agent.last_metrics["critic_loss"] < first


def test_background_evaluation_scores_the_policy_of_its_step(fast_run):
    """The final evaluation ran in the worker process; playing the final actor here with
    the same seeds gives the same returns."""
    from seqrank.envs import make_env
    from seqrank.training.evaluation import evaluate_policy
    from seqrank.training.state import episode_seed

    config, c = fast_run.config, fast_run.counters
    last = [r for r in fast_run.run_dir.read_metrics() if r["kind"] == "eval"][-1]
    assert last["step"] == config.steps and c.last_eval_return == last["eval_return"]
    seeds = [episode_seed(config.seed, 1, c.evaluations - 1, i) for i in range(1)]
    env = make_env(config.task, config.seed)
    score = evaluate_policy(fast_run.agent, env, seeds, torch.Generator())
    assert last["eval_return"] == pytest.approx(float(np.mean(score.returns)), rel=1e-4)
    assert fast_run.evaluations._worker is None  # the worker process was shut down


def test_a_fast_run_resumes_on_the_reference_path(fast_run, tmp_path):
    """Checkpoints do not depend on the path: a run killed on the fast path continues on
    the reference path from exactly the saved agent, and finishes every phase."""
    with pytest.raises(KeyboardInterrupt):
        run(tmp_path / "gpu-run", tiny_config(path="fast"), stop_at=2500)
    directory = RunDir.open(tmp_path / "gpu-run")
    state = directory.load_checkpoint()
    trainer = Trainer(tiny_config(path="reference"), directory)
    trainer.load_checkpoint(state)
    assert not trainer.fast
    assert_same_state(trainer.agent.state_dict(), state["agent"])
    trainer.train()
    rows = directory.read_metrics()
    assert [r["step"] for r in rows if r["kind"] == "eval"] == [1600, 3200]
    assert [r["step"] for r in rows if r["kind"] == "feedback"] == [1200, 1700, 2200]
