"""seqrank: reinforcement learning from human preferences with sequential and root
pairwise comparison and transitive label augmentation (SeqRank, NeurIPS 2023).

The public Python API (documented on the site's Reference, Python API page, docs/reference/api.md;
`help(seqrank.<name>)`):

- asking: `run_scheme`, `close_preferences`, `Recheck` (noise-aware augmentation),
  `Answer`, `SCHEMES`;
- training: `make_config`, `train`, `TrainConfig`, `JudgeSource`, `Segment`,
  `FeedbackSource` (the protocol a custom source implements), `SessionRequest`;
  `offline_train` (IQL on a fixed dataset);
- looking: `load_run`, `Run`, `make_env`.

Two of the names are values:

- `SCHEMES`: the comparison schemes' names, as `run_scheme` and `make_config(scheme=...)`
  take them: pairwise (the baseline), sequential, root and ranked;
- `__version__`: the package's version, as `seqrank --version` prints it.

Names are loaded on first use, so `import seqrank` stays light (no torch, no Gymnasium).
It registers seqrank's tasks with Gymnasium (`gymnasium.make("seqrank/walker_walk-v0")`,
`seqrank.registration`), at once or when Gymnasium is first imported.

Examples:
    >>> import seqrank
    >>> seqrank.SCHEMES
    ('pairwise', 'sequential', 'root', 'ranked')
    >>> print("seqrank", seqrank.__version__)
    seqrank ...
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

from seqrank.registration import register_on_import

__version__ = "0.1.0"
register_on_import()

_PUBLIC = {
    "run_scheme": "seqrank.api",
    "close_preferences": "seqrank.api",
    "make_config": "seqrank.api",
    "train": "seqrank.api",
    "offline_train": "seqrank.api",
    "load_run": "seqrank.api",
    "Run": "seqrank.api",
    "JudgeSource": "seqrank.api",
    "Segment": "seqrank.api",
    "Answer": "seqrank.types",
    "Recheck": "seqrank.feedback.checking",
    "TrainConfig": "seqrank.config",
    "FeedbackSource": "seqrank.feedback.session",
    "SessionRequest": "seqrank.feedback.session",
    "make_env": "seqrank.envs",
}
__all__ = ["SCHEMES", "__version__", *_PUBLIC]


def __getattr__(name: str) -> Any:
    if name == "SCHEMES":
        from seqrank.feedback.schemes import SchemeName

        return tuple(s.value for s in SchemeName)
    if name in _PUBLIC:
        return getattr(import_module(_PUBLIC[name]), name)
    raise AttributeError(f"module 'seqrank' has no attribute {name!r}")
