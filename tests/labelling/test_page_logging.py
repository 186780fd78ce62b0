"""Starting the labelling page's server leaves the process's logging as it found it:
uvicorn's own logging config would replace every handler and close the streams of other
libraries' (dm_control's absl handler among them), which in a test run closed pytest's
capture of stderr and in a program embedding the page silenced its logs."""

from __future__ import annotations

import io
import logging

from seqrank.labelling.app import PageServer, ServerOptions, open_hub


class _Handler(logging.StreamHandler):
    """A library's handler that, as absl's, closes its stream when it is closed."""

    def close(self) -> None:
        self.stream.close()
        super().close()


def test_the_page_server_keeps_the_handlers_it_found(tmp_path):
    stream = io.StringIO()
    handler = _Handler(stream)
    logger = logging.getLogger("a.library")
    logger.addHandler(handler)
    try:
        hub = open_hub(tmp_path, "dmc:cartpole_swingup", ServerOptions(port=0))
        server = PageServer(hub, ServerOptions(port=0))
        server.start()
        server.stop()
        hub.db.close()
        assert handler in logger.handlers and not stream.closed
        logger.warning("still heard")
        assert "still heard" in stream.getvalue()
    finally:
        logger.removeHandler(handler)
