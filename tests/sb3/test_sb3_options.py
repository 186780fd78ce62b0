"""Bad options are refused with the run config's own one-line error naming the option,
before anything is made (no folder, no page, no environment)."""

from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3 import PPO

from seqrank.config import Role, TrainConfig, resolve_config, settings_of
from seqrank.errors import SettingError
from seqrank.sb3 import PreferenceFeedback
from support.sb3_runs import LINE, TINY, feedback

BAD = [
    ({"scheme": "best"}, "unknown scheme 'best'"),
    ({"teacher": "oracle,eps_mistake=2"}, "eps_mistake"),
    ({"max_feedback": 0}, "max_feedback must be a whole number from 1"),
    (
        {"segment_length": 10, "surf_crop": 10, "reward_learner": "surf"},
        "surf_crop 10 must be smaller than segment_length",
    ),
    ({"reward_learner": "magic"}, "reward_learner"),
    ({"query_episodes": 500}, "query_episodes 500 exceeds episodes_kept"),
    ({"reward_batch": 50}, "reward_batch 50 exceeds max_feedback 40"),
    ({"feedback_frequency": 5000}, "impossible budget"),
]


@pytest.mark.parametrize(("settings", "named"), BAD)
def test_a_bad_setting_gets_the_same_error_as_seqrank_train(settings, named, tmp_path):
    with pytest.raises(ValueError) as refused:
        feedback(**settings, label_dir=tmp_path / "labels")
    assert named in str(refused.value) and "\n" not in str(refused.value)
    with pytest.raises(ValueError) as cli:  # what `seqrank train` resolves and validates
        resolve_config(LINE, "small", {**TINY, **settings})
    assert str(refused.value) == str(cli.value)
    assert not (tmp_path / "labels").exists()


@pytest.mark.parametrize(
    ("options", "named"),
    [
        ({"hidden": 64}, r"hidden is a setting of seqrank's own agent.*net_arch"),
        ({"eval_every": 500}, r"SB3's EvalCallback: learn\(\.\.\., callback=\[feedback, Eval"),
        ({"eval_episodes": 5}, "SB3's EvalCallback"),
        ({"checkpoint_every": 500}, r"SB3's CheckpointCallback.*feedback\.save\(folder\)"),
        ({"start_from": "run"}, r"a saved SB3 model: SAC\.load\(path, env=feedback\.env\)"),
        ({"parts": ("clips",)}, r"study's parts.*SAC\.load\(path, env=feedback\.env\)"),
        ({"meta_loss_weight": 1.0}, "MRN's meta update"),
        ({"learning_rate": 3e-4}, "'learning_rate' is a keyword of the SB3 model"),
        ({"bogus": 1}, "unknown setting 'bogus'; accepted: scheme, teacher"),
        ({"n_envs": 0}, "n_envs must be a whole number from 1"),
        ({"teacher": 3}, "teacher 3; accepted"),
        ({"teacher": "human"}, "teacher 'human' answers on the labelling page"),
    ],
)
def test_options_of_the_sb3_layer_are_refused_by_name(options, named, tmp_path):
    with pytest.raises(SettingError, match=named):
        feedback(**options)
    assert not list(tmp_path.iterdir())


OWN_AGENT_AND_LOOP = sorted(settings_of(Role.AGENT, Role.AGENT_FOR_FEEDBACK, Role.BOOKKEEPING))


@pytest.mark.parametrize("name", [*OWN_AGENT_AND_LOOP, "task", "reward", "warm_start"])
def test_every_setting_of_seqranks_own_agent_and_loop_is_refused_even_at_its_default(name):
    """By its role: a new agent setting is refused, not taken and silently ignored."""
    with pytest.raises(SettingError, match=f"^{name} is a setting of seqrank's own agent"):
        PreferenceFeedback(LINE, **{**TINY, name: getattr(TrainConfig, name)})


def test_every_other_setting_is_taken():
    from seqrank.sb3.settings import FEEDBACK_SETTINGS

    others = settings_of(*Role) - set(OWN_AGENT_AND_LOOP)
    assert others - set(FEEDBACK_SETTINGS) == {"task", "reward", "warm_start", "scale"}


def test_a_bad_task_or_environment_is_refused_by_name():
    with pytest.raises(SettingError, match="unknown task 'walker_jog'"):
        PreferenceFeedback("walker_jog")
    with pytest.raises(SettingError, match="env 42; accepted: a seqrank task name"):
        PreferenceFeedback(42)


def test_pebbles_pieces_are_refused_for_an_on_policy_agent():
    fb = feedback(pretrain=True)
    with pytest.raises(SettingError, match="pretrain True: PPO is on-policy"):
        PPO("MlpPolicy", fb.env, n_steps=64, batch_size=32).learn(64, callback=fb)


def test_a_budget_that_only_pre_training_makes_impossible_says_how_to_drop_it():
    """PPO does not pre-train, but the budget is checked before the agent is known: with
    the preset's pre-training the hint names pretrain=False."""
    settings = {k: v for k, v in TINY.items() if k != "unsup_steps"}
    with pytest.raises(SettingError, match=r"impossible budget.*pass pretrain=False"):
        PreferenceFeedback(LINE, **{**settings, "steps": 1500})
    PreferenceFeedback(LINE, **{**settings, "steps": 1500}, pretrain=False)  # fits without


def test_seqranks_own_gymnasium_environment_is_taken_as_it_is():
    import gymnasium

    import seqrank  # noqa: F401  (registers seqrank/...)

    taught = PreferenceFeedback(gymnasium.make("seqrank/cartpole_swingup-v0"), **TINY)
    assert taught.state.task.episode_length == 1000  # it ends its episodes itself


def test_a_judge_that_does_not_answer_with_an_answer_is_named():
    taught = feedback(teacher=lambda first, second: 1)
    model = PPO("MlpPolicy", taught.env, n_steps=100, batch_size=50, seed=0)
    with pytest.raises(TypeError, match=r"the judge returned 1; accepted: a seqrank.Answer"):
        model.learn(600, callback=taught)


def test_reward_takes_a_batch_and_says_so():
    taught = feedback()
    with pytest.raises(ValueError, match=r"reward\(\) takes a batch: observations \(N, 2\)"):
        taught.reward(np.zeros(2), np.zeros(1))


def test_feedback_saved_for_your_own_environment_is_loaded_only_with_it(tmp_path):
    from support.sb3_envs import make_line

    PreferenceFeedback(make_line(), **TINY).save(tmp_path / "saved")
    with pytest.raises(ValueError, match=r"made for your own environment .*pass it again"):
        PreferenceFeedback.load(tmp_path / "saved")
    assert PreferenceFeedback.load(tmp_path / "saved", make_line()).state.task.obs_dim == 2


def test_a_crowd_teacher_takes_the_runs_evidence_settings():
    """`overlap_until` and `closure_checks` reach an SB3 run's crowd, as `seqrank train`'s."""
    crowd = feedback(teacher="crowd:oracle+oracle", overlap=0.3, overlap_until=7, closure_checks=1)
    source = crowd.state.run.source
    assert (source.overlap, source.overlap_until, source.closure_checks) == (0.3, 7, True)
