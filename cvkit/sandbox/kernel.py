"""The kernel of a notebook's grading run: jupyter_client's, without its idle waits.

jupyter_client waits for a kernel it has just started until its IOPub channel has been silent
for 0.2 s, and polls a kernel it has killed every 0.1 s: about 0.3 s of a notebook's run in
which nothing happens (a tenth of a short chapter's). Both are plugged in where nbclient and
jupyter_client expect them (``NotebookClient.kernel_manager_class``, the manager's client
factory):

- :class:`ReadyClient` knows the kernel is ready when it has answered a ``kernel_info`` request
  on the shell channel **and** announced on IOPub that it is idle after that same request —
  proof that IOPub is connected, with nothing left of the start-up in it that concerns a
  cell (nbclient keeps only the IOPub messages whose parent is the cell it runs).
- :class:`KernelManager` looks every 5 ms whether a killed kernel has ended, and starts
  ipykernel without its debugger (:data:`LAUNCHER`).

Everything the kernel prints, and when it is interrupted, is as before: only the waiting is
shorter.

ipykernel imports ``debugpy`` as it starts whenever it is installed (JupyterLab's debugger is),
0.08 s of CPU in every notebook's run; a grading run never debugs. A Python kernel whose command
is ipykernel's launcher (``python -m ipykernel_launcher ...``) is started by :data:`LAUNCHER`
instead: the same steps (the working folder off ``sys.path`` while ipykernel loads, so that a
student's file cannot stand in for one of its modules), with ``debugpy`` marked as absent.
"""
from __future__ import annotations

import time
from queue import Empty

from jupyter_client.asynchronous import AsyncKernelClient
from jupyter_client.manager import AsyncKernelManager
from traitlets import default

#: how long a kernel_info request may go unanswered on the shell channel before it is sent again
ATTEMPT_SECONDS = 1.0
#: how long the kernel's "idle" after a reply may take on IOPub; longer means IOPub was not yet
#: connected when it was sent (a subscription takes effect a little after the connection)
IOPUB_SECONDS = 0.05
#: how often a killed kernel is looked at until it has ended
KILL_POLL_SECONDS = 0.005
#: ipykernel's launcher (``ipykernel_launcher.py``) with ``debugpy`` marked absent: ipykernel then
#: starts without its debugger (see the module docstring)
LAUNCHER = """import sys
from pathlib import Path
if sys.path[0] == "" or Path(sys.path[0]) == Path.cwd():
    del sys.path[0]
sys.modules.setdefault("debugpy", None)
from ipykernel import kernelapp
kernelapp.launch_new_instance()
"""


class ReadyClient(AsyncKernelClient):
    """A kernel client whose ``wait_for_ready`` returns as soon as the kernel is ready (see the
    module docstring); raises :class:`RuntimeError` as jupyter_client's does when the kernel
    dies or ``timeout`` seconds pass."""

    async def wait_for_ready(self, timeout: float | None = None) -> None:
        deadline = time.monotonic() + (float("inf") if timeout is None else timeout)
        while True:
            request = self.kernel_info()
            if await self._answered(request, min(ATTEMPT_SECONDS, deadline - time.monotonic())):
                return
            if not await self._async_is_alive():
                raise RuntimeError("Kernel died before replying to kernel_info")
            if time.monotonic() > deadline:
                raise RuntimeError(f"Kernel didn't respond in {timeout:g} seconds")

    async def _answered(self, request: str, seconds: float) -> bool:
        """Whether the kernel replied to ``request`` within ``seconds`` and then said on IOPub
        that it is idle within :data:`IOPUB_SECONDS`."""
        until = time.monotonic() + max(0.0, seconds)
        replied = idle = False
        while not replied:
            try:
                message = await self.shell_channel.get_msg(timeout=max(0.0, until - time.monotonic()))
            except Empty:
                return False
            if message.get("parent_header", {}).get("msg_id") == request and message["msg_type"] == "kernel_info_reply":
                self._handle_kernel_info_reply(message)
                replied = True
        until = time.monotonic() + IOPUB_SECONDS
        while not idle:
            try:
                message = await self.iopub_channel.get_msg(timeout=max(0.0, until - time.monotonic()))
            except Empty:
                return False
            idle = (message.get("parent_header", {}).get("msg_id") == request and message["msg_type"] == "status"
                    and message["content"].get("execution_state") == "idle")
        return True


class KernelManager(AsyncKernelManager):
    """jupyter_client's kernel manager with :class:`ReadyClient` clients, looking every
    :data:`KILL_POLL_SECONDS` whether a killed kernel has ended, starting ipykernel with
    :data:`LAUNCHER`."""

    @default("client_factory")
    def _ready_client(self) -> type:
        return ReadyClient

    def format_kernel_cmd(self, extra_arguments: list[str] | None = None) -> list[str]:
        """The kernel's command, with ``-m ipykernel_launcher`` replaced by ``-c`` :data:`LAUNCHER`."""
        command = super().format_kernel_cmd(extra_arguments)
        for index in range(1, len(command) - 1):
            if command[index:index + 2] == ["-m", "ipykernel_launcher"]:
                return command[:index] + ["-c", LAUNCHER] + command[index + 2:]
        return command

    async def _async_wait(self, pollinterval: float = KILL_POLL_SECONDS) -> None:
        await super()._async_wait(pollinterval=min(pollinterval, KILL_POLL_SECONDS))
