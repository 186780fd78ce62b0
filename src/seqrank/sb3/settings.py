"""A `PreferenceFeedback`'s settings: the feedback-session options of `seqrank train`,
resolved and checked by the run config's own code (`config.resolve_config`, `validate`),
so a bad value is refused with the same one-line `SettingError` before anything is made.

The settings of seqrank's own agent and loop (network sizes, learning rates, discount,
evaluation, ...: those whose role says so, `config.Role`) are the SB3 model's and its
callbacks', so they are refused here, naming where they go instead.
"""

from __future__ import annotations

import numbers
from dataclasses import fields, replace
from typing import Any

import numpy as np

from seqrank.config import Role, TrainConfig, resolve_config, settings_of
from seqrank.errors import SettingError, setting
from seqrank.scale import resolve_scale

# SB3's own callbacks in place of seqrank's evaluation, checkpoints and fine-tuning
_EVAL = (
    "learn(..., callback=[feedback, EvalCallback(eval_env, eval_freq=..., n_eval_episodes=...)]),"
    " its eval_env the task itself, scored by the true reward"
)
_CONTINUE = "SAC.load(path, env=feedback.env), then its learn(..., callback=feedback)"
# where a refused setting goes with Stable-Baselines3, or why it has no place there; the
# settings named here are refused beside seqrank's own agent and loop
ELSEWHERE = {
    "hidden": "the network: SAC('MlpPolicy', env, policy_kwargs=dict(net_arch=[256, 256]))",
    "layers": "the network: SAC('MlpPolicy', env, policy_kwargs=dict(net_arch=[256, 256]))",
    "task": "the environment: the first argument, PreferenceFeedback('walker_walk', ...)",
    "reward": "a baseline that asks nothing: train the SB3 model on the environment itself",
    "warm_start": "not there: RIME's warm start fits the reward model in seqrank's own "
    "pre-training; pretrain=True trains the SB3 agent on the state-entropy reward only",
    "eval_every": f"SB3's EvalCallback: {_EVAL}",
    "eval_episodes": f"SB3's EvalCallback: {_EVAL}",
    "checkpoint_every": "SB3's CheckpointCallback: learn(..., callback=[feedback, "
    "CheckpointCallback(save_freq=..., save_path=..., save_replay_buffer=True)]), and "
    "feedback.save(folder) for the feedback",
    "start_from": f"a saved SB3 model: {_CONTINUE}",
    "parts": "not there: the study's parts choose the clips of seqrank's own fine-tuning "
    f"sessions; to fine-tune an SB3 agent start from its saved model, {_CONTINUE}",
    "hybrid_replay": "not there: QPA's hybrid replay is seqrank's own agent's sampling",
    "hybrid_episodes": "not there: QPA's hybrid replay is seqrank's own agent's sampling",
    "meta_update_frequency": "not there: MRN's meta update wraps seqrank's own agent's update",
    "meta_loss_weight": "not there: MRN's meta update wraps seqrank's own agent's update",
}
# what the SB3 model and its callbacks replace: seqrank's agent (and what it does for
# feedback), its loop's evaluation and checkpoints
OWN_AGENT_AND_LOOP = settings_of(Role.AGENT, Role.AGENT_FOR_FEEDBACK, Role.BOOKKEEPING)
REFUSED_SETTINGS = OWN_AGENT_AND_LOOP | set(ELSEWHERE)
FEEDBACK_SETTINGS = tuple(
    f.name for f in fields(TrainConfig) if f.name not in REFUSED_SETTINGS and f.name != "scale"
)
# agents whose update PEBBLE's pieces (entropy pre-training, critic reset) fit by default
PEBBLE_AGENTS = ("SAC", "TD3")
# keywords of SB3's models that users pass here by mistake
SB3_MODEL_KEYWORDS = frozenset(
    {
        "learning_rate",
        "batch_size",
        "buffer_size",
        "learning_starts",
        "gamma",
        "train_freq",
        "gradient_steps",
        "ent_coef",
        "policy_kwargs",
        "n_steps",
        "n_epochs",
    }
)


def check_names(settings: dict[str, Any]) -> None:
    for name in settings:
        if name in REFUSED_SETTINGS:
            where = ELSEWHERE.get(
                name, "the SB3 model's own, e.g. SAC(..., learning_rate=..., batch_size=...)"
            )
            raise SettingError(
                f"{setting(name)} is a setting of seqrank's own agent and loop; with "
                f"Stable-Baselines3 it is {where}"
            )
        if name in SB3_MODEL_KEYWORDS:
            raise SettingError(
                f"{name!r} is a keyword of the SB3 model, not of the feedback: "
                f"SAC('MlpPolicy', feedback.env, {name}=...)"
            )
        if name not in FEEDBACK_SETTINGS:
            raise SettingError(
                f"unknown setting {name!r}; accepted: {', '.join(FEEDBACK_SETTINGS)}, scale, "
                "pretrain, reset_critic, n_envs, wait_for_feedback, page, label_dir"
            )


def feedback_config(
    task: str, preset_task: str, scale: str, settings: dict[str, Any]
) -> TrainConfig:
    """The run config of the feedback: `preset_task`'s presets (the task itself, or a
    Gymnasium stand-in for an environment object), `scale` and the user's settings,
    validated as `seqrank train` validates them; `task` names it in saved settings."""
    check_names(settings)
    from seqrank.training.runtime import resolve_device

    device = str(settings.get("device", "auto"))
    if scale == "auto":
        scale = resolve_scale(scale, resolve_device(device))
    config = resolve_config(preset_task, scale, {**settings, "task": preset_task})
    return replace(config, task=task)


def without_pretraining(config: TrainConfig) -> TrainConfig:
    """No pre-training phase: the first session comes after `seed_steps`."""
    return replace(config, unsup_steps=0)


def pebble_default(agent: str, wanted: bool | None, on_policy: bool, name: str) -> bool:
    """Whether one of PEBBLE's pieces is on for `agent` (None: on for SAC and TD3)."""
    if wanted and on_policy:
        raise SettingError(
            f"{setting(name)} True: {agent} is on-policy (no replay buffer to pre-train on, no "
            f"critic to reset); accepted for {agent}: False or None"
        )
    return agent in PEBBLE_AGENTS if wanted is None else bool(wanted)


def sb3_options(env: Any, **given: Any) -> dict[str, Any]:
    """`PreferenceFeedback`'s own keywords checked, as Python's types: `pretrain` and
    `reset_critic` True, False or None, `wait_for_feedback` True or False, `n_envs` a whole
    number from 1 (more only for a task name)."""
    options: dict[str, Any] = {
        name: _flag(name, given[name], True) for name in ("pretrain", "reset_critic")
    }
    options["wait_for_feedback"] = _flag("wait_for_feedback", given["wait_for_feedback"], False)
    options["n_envs"] = _n_envs(given["n_envs"], env)
    return options


def check_page_keywords(env: Any, teacher: Any, label_dir: Any, page: Any) -> None:
    """`label_dir` and `page` go with `teacher="human"` (and it needs `label_dir`)."""
    human = isinstance(teacher, str) and teacher == "human"
    for name, value in (("label_dir", label_dir), ("page", page)):
        if value is not None and not human:
            told = teacher if isinstance(teacher, str) else type(teacher).__name__
            raise SettingError(
                f"{setting(name)} is for teacher='human' only (the labelling page), but the "
                f"teacher is {told!r}: leave {name} out, or pass teacher='human'"
            )
    if human and (label_dir is None or not isinstance(env, str)):
        raise SettingError(
            f"{setting('teacher')} 'human' answers on the labelling page: give a task name "
            "(its clips are re-rendered) and label_dir, the folder of the label database"
        )


def _flag(name: str, value: Any, optional: bool) -> bool | None:
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if value is None and optional:
        return None
    accepted = (
        "True, False or None (None: on for SAC and TD3 only)" if optional else "True or False"
    )
    raise SettingError(f"{setting(name)} must be {accepted}, got {value!r}")


def _n_envs(value: Any, env: Any) -> int:
    count = int(value) if isinstance(value, numbers.Integral) else 0
    if isinstance(value, bool) or count < 1:
        raise SettingError(f"{setting('n_envs')} must be a whole number from 1, got {value!r}")
    if count > 1 and not isinstance(env, str):
        raise SettingError(
            f"{setting('n_envs')} {count} makes environments of a task name; for your own "
            "environment pass a VecEnv of as many"
        )
    return count
