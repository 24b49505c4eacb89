"""The grading run's kernel client (cvkit.sandbox.kernel): ready once the kernel has answered a
kernel_info request and said on IOPub that it is idle after that same request; asks again when
IOPub missed it; gives up as jupyter_client does when the kernel dies or the time is up."""
import asyncio
from queue import Empty

import pytest

from cvkit.sandbox import kernel
from cvkit.sandbox.kernel import ReadyClient


class _Channel:
    """A channel whose messages arrive in the given order (Empty once they are used up)."""

    def __init__(self):
        self.waiting = []

    async def get_msg(self, timeout=None):
        if not self.waiting:
            raise Empty
        return self.waiting.pop(0)


def _message(kind, parent, **content):
    return {"msg_type": kind, "parent_header": {"msg_id": parent} if parent else {}, "content": content}


class _Kernel:
    """Plays a kernel: answers each kernel_info request; the IOPub messages of the first
    ``lost`` requests never arrive (a subscription not yet in effect)."""

    def __init__(self, lost=0, alive=True, replies=True):
        self.requests, self.lost, self.alive, self.replies = [], lost, alive, replies
        self.shell, self.iopub = _Channel(), _Channel()
        self.shell.waiting.append(_message("kernel_info_reply", "someone else's request", status="ok"))
        self.iopub.waiting.append(_message("status", None, execution_state="starting"))

    def kernel_info(self):
        request = f"request-{len(self.requests)}"
        self.requests.append(request)
        if self.replies:
            self.shell.waiting.append(_message("kernel_info_reply", request, status="ok"))
        if len(self.requests) > self.lost:
            self.iopub.waiting += [_message("status", request, execution_state="busy"),
                                   _message("status", request, execution_state="idle")]
        return request


def _client(fake, monkeypatch):
    client = ReadyClient.__new__(ReadyClient)  # no sockets: the channels are the fake kernel's
    monkeypatch.setattr(ReadyClient, "shell_channel", property(lambda self: fake.shell), raising=False)
    monkeypatch.setattr(ReadyClient, "iopub_channel", property(lambda self: fake.iopub), raising=False)
    monkeypatch.setattr(client, "kernel_info", fake.kernel_info, raising=False)
    handled = []
    monkeypatch.setattr(client, "_handle_kernel_info_reply", handled.append, raising=False)

    async def alive():
        return fake.alive

    monkeypatch.setattr(client, "_async_is_alive", alive, raising=False)
    return client, handled


def test_ready_after_the_reply_and_the_idle_of_the_same_request(monkeypatch):
    fake = _Kernel()
    client, handled = _client(fake, monkeypatch)
    asyncio.run(client.wait_for_ready(timeout=5))
    assert fake.requests == ["request-0"]
    assert [m["parent_header"]["msg_id"] for m in handled] == ["request-0"]  # not someone else's reply
    assert fake.iopub.waiting == []  # the start-up's messages are read, up to this request's idle


def test_asks_again_when_iopub_missed_the_first_answer(monkeypatch):
    fake = _Kernel(lost=2)
    client, handled = _client(fake, monkeypatch)
    asyncio.run(client.wait_for_ready(timeout=5))
    assert fake.requests == ["request-0", "request-1", "request-2"]
    assert handled[-1]["parent_header"]["msg_id"] == "request-2"


def test_a_dead_kernel_is_reported(monkeypatch):
    fake = _Kernel(lost=10**6, alive=False)
    client, _ = _client(fake, monkeypatch)
    with pytest.raises(RuntimeError, match="died"):
        asyncio.run(client.wait_for_ready(timeout=5))


def test_gives_up_when_the_time_is_up(monkeypatch):
    fake = _Kernel(replies=False)
    client, _ = _client(fake, monkeypatch)
    monkeypatch.setattr(kernel, "ATTEMPT_SECONDS", 0.01)
    with pytest.raises(RuntimeError, match="didn't respond"):
        asyncio.run(client.wait_for_ready(timeout=0.05))


def test_the_notebook_run_waits_with_this_client(monkeypatch, tmp_path):
    from cvkit.sandbox.notebook_run import execute

    used = []
    original = ReadyClient.wait_for_ready

    async def recorded(self, timeout=None):
        used.append(type(self))
        await original(self, timeout)

    monkeypatch.setattr(ReadyClient, "wait_for_ready", recorded)
    notebook = {"nbformat": 4, "nbformat_minor": 5,
                "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"}},
                "cells": [{"cell_type": "code", "id": "c1", "metadata": {}, "execution_count": None, "outputs": [],
                           "source": "print('first output kept')"}]}
    executed = execute(notebook, str(tmp_path))
    assert used == [ReadyClient]
    assert "".join(executed["cells"][0]["outputs"][0]["text"]) == "first output kept\n"


def _run(source, folder):
    from cvkit.sandbox.notebook_run import execute

    notebook = {"nbformat": 4, "nbformat_minor": 5,
                "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"}},
                "cells": [{"cell_type": "code", "id": "c1", "metadata": {}, "execution_count": None, "outputs": [],
                           "source": source}]}
    return "".join("".join(o.get("text", "")) for o in execute(notebook, str(folder))["cells"][0]["outputs"])


def test_the_kernel_starts_without_its_debugger(tmp_path):
    """ipykernel's launcher, with debugpy marked absent (it costs every run 0.08 s of CPU); the
    kernel's sys.path is that of a kernel ipykernel's own launcher starts."""
    from jupyter_client.manager import start_new_kernel

    probe = "import sys; print(sys.modules.get('debugpy', 'never imported')); print(sys.path)"
    printed = _run(probe, tmp_path).splitlines()
    assert printed[0] == "None"
    manager, client = start_new_kernel(kernel_name="python3", cwd=str(tmp_path))
    try:
        texts = []
        client.execute_interactive("import sys; print(sys.path)",
                                   output_hook=lambda m: texts.append(m["content"].get("text", "")))
    finally:
        client.stop_channels()
        manager.shutdown_kernel(now=True)
    assert printed[1] == "".join(texts).strip()


def test_a_students_file_cannot_stand_in_for_a_kernel_module(tmp_path):
    """The working folder (the submission) is off sys.path while ipykernel loads, as in
    ipykernel's own launcher: a file named like one of its modules is not what starts."""
    (tmp_path / "zmq.py").write_text("raise SystemExit('the student file was imported')\n")
    (tmp_path / "ipykernel.py").write_text("raise SystemExit('the student file was imported')\n")
    assert _run("print('ran')", tmp_path) == "ran\n"


@pytest.mark.parametrize("argv, expected", [
    (["/env/bin/python", "-m", "ipykernel_launcher", "-f", "{connection_file}"],
     ["/env/bin/python", "-c", kernel.LAUNCHER, "-f", "CONNECTION"]),
    (["/env/bin/python", "-Xfrozen_modules=off", "-m", "ipykernel_launcher", "-f", "{connection_file}"],
     ["/env/bin/python", "-Xfrozen_modules=off", "-c", kernel.LAUNCHER, "-f", "CONNECTION"]),
    (["/opt/other-kernel", "-m", "something_else", "{connection_file}"],
     ["/opt/other-kernel", "-m", "something_else", "CONNECTION"]),
])
def test_only_ipykernels_launcher_is_replaced(monkeypatch, argv, expected):
    from jupyter_client.manager import AsyncKernelManager

    def format_plain(self, extra_arguments=None):
        return [a.replace("{connection_file}", "CONNECTION") for a in argv + list(extra_arguments or [])]

    monkeypatch.setattr(AsyncKernelManager, "format_kernel_cmd", format_plain)
    manager = kernel.KernelManager()
    assert manager.format_kernel_cmd(["--x=1"]) == expected + ["--x=1"]
