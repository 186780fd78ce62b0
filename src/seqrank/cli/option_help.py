"""What each `seqrank train` setting means, for `--help` (docs/reference/cli.md lists them
all). Kept beside the parser so that a new TrainConfig field without a line here fails a
test, not a user."""

from __future__ import annotations

MEANINGS = {
    "task": "a paper task, dmc:domain_task, metaworld:name-v3, block:place, gym:ID or "
    "module.path:factory",
    "scheme": "how questions are asked: pairwise, sequential, root, ranked",
    "teacher": "oracle, mistake, noisy, skip, myopic, equal (optionally ,knob=value...), "
    "replay:FILE, or a simulated crowd crowd:oracle+mistake+noisy (a person answers "
    "through `seqrank label online`, a team with its --annotators)",
    "reward": "learned (from preferences); true (the environment's reward) or none (the "
    "untrained reward model): baselines that ask nothing",
    "backbone": "pebble or mrn",
    "seed": "the run's seed; every episode is seeded from it",
    "steps": "environment steps of the whole run",
    "device": "auto, cpu, cuda",
    "path": "reference, fast, or auto (fast on CUDA; on a CPU with native bf16 the fast path "
    "in bf16 where measured faster; on a CPU the fast path leaves one core to evaluation)",
    "precision": "fp32, tf32, bf16 (fast path), or auto",
    "hidden": "SAC: units per hidden layer",
    "layers": "SAC: hidden layers",
    "batch": "SAC: transitions per update",
    "actor_lr": "SAC: actor learning rate",
    "critic_lr": "SAC: critic learning rate",
    "alpha_lr": "SAC: temperature learning rate",
    "init_temperature": "SAC: the temperature at the start",
    "discount": "SAC: discount factor, in (0, 1]",
    "tau": "SAC: soft target update rate, in (0, 1]",
    "target_update_every": "SAC: updates between target updates",
    "seed_steps": "random-action steps before any update",
    "unsup_steps": "PEBBLE's unsupervised pre-training steps (state-entropy reward)",
    "knn_k": "pre-training: k of the k-nearest-neighbour entropy estimate",
    "updates_after_reset": "updates right after the first session's critic reset",
    "max_feedback": "questions in the whole run",
    "reward_batch": "questions per session",
    "feedback_frequency": "steps between sessions",
    "segment_length": "steps per compared segment",
    "augment": "full (the paper's transitive closure) or checked (noise-aware: re-checks "
    "and trusted paths)",
    "recheck_gain": "checked: ask an answer again when it would imply this many new pairs "
    "(unless the fitted model agrees with a teacher never contradicted)",
    "recheck_twice_gain": "checked: ... twice from this many on, once contradicted",
    "path_unchecked": "checked: unconfirmed answers allowed on an inferred pair's path",
    "selection": "which segments are asked about: uniform, disagreement, entropy",
    "segment_order": "a session's new segments as drawn (uniform) or in the order they "
    "were collected (collection: later segments challenge an early root)",
    "oversample": "disagreement and entropy: candidates per question",
    "episodes_kept": "recent episodes that segments are cut from",
    "overlap": "a crowd's share of answers also asked of a second member, for agreement (0 to 1)",
    "overlap_until": "a crowd: every answer of a member with fewer than N answers shared with "
    "another member is asked again (evidence for the flags early; 0: the overlap only)",
    "closure_checks": "a crowd: 1 asks a second opinion on a pair the owner's chain inferred "
    "(one answer checks several of theirs), where there is one; 0: on the asked pair",
    "crowd_weighting": "reliability (each crowd label is the probability that its annotator "
    "is right), drop (a flagged annotator's labels left out), reask (as drop, and each "
    "question of an annotator flagged before a session asked again of one who is not, in "
    "place of the overlap's opinions on it: person-time, not questions), soften (a flagged "
    "annotator's labels each the probability that it is right, left out at 1/2 or less) or "
    "none (answers as given)",
    "annotators": "label online: a team at the page, comma-separated names (each gets an "
    "address of their own; ASCII letters, digits, '-', '_' and '.', starting with a letter, "
    "'operator' reserved)",
    "query_episodes": "QPA: cut new segments from the last N episodes only (0: all kept)",
    "hybrid_replay": "QPA: share of each agent batch from recent transitions while "
    "feedback is asked for (0: off)",
    "hybrid_episodes": "QPA: hybrid replay's recent window, in episodes",
    "record_states": "1: keep physics states, so labelled segments can be re-rendered",
    "start_from": "fine-tuning: a saved run directory to start from",
    "parts": "fine-tuning: what the sessions' clips show (Guides, The user study)",
    "reward_ensemble": "reward model: ensemble members",
    "reward_hidden": "reward model: units per hidden layer",
    "reward_layers": "reward model: hidden layers",
    "reward_lr": "reward model: learning rate",
    "reward_minibatch": "reward model: labelled pairs per minibatch",
    "reward_epochs": "reward model: most epochs per session",
    "reward_stop_accuracy": "reward model: stop a session's training at this accuracy",
    "reward_stop_on": "which labels that accuracy counts: all (asked and inferred, PEBBLE's "
    "rule) or asked (the asked pairs only)",
    "reward_learner": "plain (Bradley-Terry), surf (pseudo-labels, crops) or rime (robust "
    "label selection)",
    "surf_threshold": "SURF: confidence a pseudo-label needs",
    "surf_unlabelled_ratio": "SURF: unlabelled pairs cut before a fit per question asked so far "
    "(at most 10 000)",
    "surf_unlabelled_batch": "SURF: unlabelled pairs per labelled pair of a minibatch",
    "surf_loss_weight": "SURF: weight of the pseudo-label loss",
    "surf_crop": "SURF: most steps a temporal crop removes",
    "rime_alpha": "RIME: alpha of the loss bound -ln(rho) + alpha * rho",
    "rime_beta_max": "RIME: the uncertainty weight at the start",
    "rime_beta_min": "RIME: the uncertainty weight at the end",
    "rime_decay_updates": "RIME: reward-training epochs over which beta falls to its floor",
    "rime_tau_upper": "RIME: flip a label the model gives a probability below this (< 0.5)",
    "rime_min_epochs": "RIME: epochs a fit runs before its accuracy may stop it",
    "warm_start": "1: RIME's warm start of the reward model during pre-training",
    "meta_update_frequency": "MRN: steps between meta updates",
    "meta_loss_weight": "MRN: weight of the meta loss",
    "eval_every": "steps between evaluations",
    "eval_episodes": "episodes per evaluation",
    "checkpoint_every": "steps between checkpoints (written at an episode end)",
    "heldout_pairs": "held-out pairs that measure the reward model's accuracy",
}
