"""The meshcat window o2m draws into: it records the scene in-process, as the meshcat server
would, exports it as one self-contained HTML page, and starts a server only when a live view is
asked for.
"""

from __future__ import annotations

import html as _html
import webbrowser
from collections.abc import Iterable
from pathlib import Path
from typing import Any

try:
    import meshcat
    import umsgpack
except ImportError as _exc:  # pragma: no cover - meshcat is in environment.txt
    raise ImportError("o2m.viz needs meshcat: pip install meshcat") from _exc

from o2m.viz.frames import ViewerError

_MESHCAT_JS = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"


class _Node:
    __slots__ = ("object", "properties", "transform")

    def __init__(self) -> None:
        self.object: bytes | None = None
        self.properties: dict[str, bytes] = {}
        self.transform: bytes | None = None


class _Window:
    """A meshcat window that records the scene (as the meshcat server does) in-process.

    Commands are packed with single-precision floats. A meshcat server is started (or joined,
    with ``zmq_url``) by :meth:`connect`, which replays the recorded scene; from then on every
    command also goes to the server.
    """

    def __init__(self) -> None:
        self.nodes: dict[tuple[str, ...], _Node] = {}
        self.animation: bytes | None = None
        self.server_proc: Any = None
        self.zmq_socket: Any = None
        self.web_url: str | None = None

    # meshcat's ViewerWindow interface
    def send(self, command: Any) -> None:
        data = command.lower()
        packed = umsgpack.packb(data, force_float_precision="single")
        kind, path = data["type"], tuple(p for p in data["path"].split("/") if p)
        if kind == "set_animation":
            self.animation = packed
        elif kind == "delete":
            for key in [k for k in self.nodes if k[:len(path)] == path]:
                del self.nodes[key]
        else:
            node = self.nodes.setdefault(path, _Node())
            if kind == "set_object":
                node.object, node.properties = packed, {}
            elif kind == "set_transform":
                node.transform = packed
            elif kind == "set_property":
                node.properties[data["property"]] = packed
        if self.zmq_socket is not None:
            self._forward(kind, data["path"], packed)

    def _forward(self, kind: str, path: str, packed: bytes) -> None:
        self.zmq_socket.send_multipart([kind.encode("utf-8"), path.encode("utf-8"), packed])
        self.zmq_socket.recv()

    def commands(self) -> Iterable[tuple[str, str, bytes]]:
        """(type, path, packed command) of the recorded scene, animation last."""
        for path, node in self.nodes.items():
            p = "/" + "/".join(path)
            if node.object is not None:
                yield "set_object", p, node.object
            for packed in node.properties.values():
                yield "set_property", p, packed
            if node.transform is not None:
                yield "set_transform", p, node.transform
        if self.animation is not None:
            yield "set_animation", "", self.animation

    def get_scene(self, title: str = "o2m") -> str:
        import base64

        cmds = "".join(
            f'fetch("data:application/octet-binary;base64,{base64.b64encode(packed).decode("ascii")}")'
            ".then(r => r.arrayBuffer()).then(b => viewer.handle_command_bytearray(new Uint8Array(b)));\n"
            for _, _, packed in self.commands())
        js = _MESHCAT_JS.read_text(encoding="utf-8")
        return (
            "<!DOCTYPE html>\n<html>\n<head><meta charset=utf-8><title>" + _html.escape(title) + "</title>\n"
            "<style>body {margin: 0;} #meshcat-pane {width: 100vw; height: 100vh; overflow: hidden;}</style>\n"
            "</head>\n<body>\n<div id=\"meshcat-pane\"></div>\n<script>\n" + js + "\n</script>\n<script>\n"
            "var viewer = new MeshCat.Viewer(document.getElementById(\"meshcat-pane\"));\n" + cmds +
            "</script>\n</body>\n</html>\n"
        )

    def connect(self, zmq_url: str | None = None) -> None:
        """Start a meshcat server (or connect to ``zmq_url``) and send it the recorded scene."""
        if self.zmq_socket is not None:
            return
        import zmq

        if zmq_url is None:
            from meshcat.servers.zmqserver import start_zmq_server_as_subprocess

            self.server_proc, zmq_url, self.web_url = start_zmq_server_as_subprocess()
        sock = zmq.Context.instance().socket(zmq.REQ)
        sock.connect(zmq_url)
        if self.web_url is None:
            sock.send(b"url")
            self.web_url = sock.recv().decode("utf-8")
        self.zmq_socket = sock
        for kind, path, packed in self.commands():
            self._forward(kind, path, packed)

    def open(self) -> None:
        self.connect()
        webbrowser.open(str(self.web_url), new=2)

    def wait(self) -> str:
        self.connect()
        self.zmq_socket.send(b"wait")
        return self.zmq_socket.recv().decode("utf-8")

    def get_image(self) -> Any:
        raise ViewerError("images need a browser connected to a meshcat server: use Viewer.open() "
                          "and meshcat's own Visualizer.get_image, or screenshot the exported HTML")

    def close(self) -> None:
        if self.zmq_socket is not None:
            self.zmq_socket.close(linger=0)
            self.zmq_socket = None
        if self.server_proc is not None:
            self.server_proc.kill()
            self.server_proc.wait()
            for stream in (self.server_proc.stdout, self.server_proc.stderr):
                if stream is not None:
                    stream.close()
            self.server_proc = None
