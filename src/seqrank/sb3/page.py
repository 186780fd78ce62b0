"""A person at the labelling page as the teacher of an SB3 agent (`teacher="human"`):
the page's server runs in this process, sessions wait for the person's answers."""

from __future__ import annotations

from pathlib import Path

from seqrank.config import TrainConfig
from seqrank.labelling.app import PageServer, ServerOptions, close_hub, open_hub, record_task
from seqrank.labelling.human import Hub, HumanSource
from seqrank.labelling.page_state import Phase

RUN_NAME = "sb3"  # the run's name inside the labelling database


class LabellingPage:
    def __init__(self, hub: Hub, server: PageServer, directory: Path):
        self.hub, self.server, self.directory = hub, server, directory

    @property
    def url(self) -> str:
        return self.server.url

    def training(self, step: int) -> None:
        """Tell the page the agent is training (between sessions)."""
        hub = self.hub
        hub.state.show_training(
            f"the agent is training: step {step:,}", lambda: hub.mode.still_asking(hub)
        )

    def close(self) -> None:
        self.hub.state.move(Phase.DONE, "training finished: thank you")
        self.server.stop()
        close_hub(self.hub, self.directory, lambda text: None)


def open_page(
    directory: Path,
    config: TrainConfig,
    obs_dim: int,
    act_dim: int,
    options: ServerOptions | None,
) -> tuple[LabellingPage, HumanSource]:
    """Serve the page for `config.task` from `directory` (its label database and clips)."""
    options = options if options is not None else ServerOptions()
    directory.mkdir(parents=True, exist_ok=True)
    hub = open_hub(directory, config.task, options)
    record_task(hub.db, config.task, obs_dim, act_dim, config.segment_length)
    hub.state.plan(config.sessions)
    server = PageServer(hub, options)
    server.start()
    return LabellingPage(hub, server, directory), HumanSource(hub, RUN_NAME, config.seed)
