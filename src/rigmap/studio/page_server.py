"""The studio's own pages (Pose and Play): fixed files and one websocket per page.

Our own pages, not viser's client, where a frame must reach the screen on time on two cores
without a GPU: viser's client holds each incoming batch to the server's send spacing and
re-renders its React tree, about 45 ms (biped) to 85 ms (face) of a drag before rigmap
computed anything, and Play's frames reached the page up to 65 ms late at p99 (measured,
docs/studio.md). These pages send each input at once and draw what comes back on the next
frame, with plain WebGL.

Served: the routes of the :data:`PAGES` it has (a Play page only when there are
latent models), fixed texts from the package; no path from a request ever reaches the file
system. Each page's websocket (``/<page>/ws``) takes JSON commands,
handed to its channel (which checks them), and sends binary messages (:func:`encode`). A
websocket opened from a page of another origin is refused: a web page elsewhere cannot
drive the studio.
"""

from __future__ import annotations

import http
import json
import threading
from collections import deque
from functools import partial
from importlib import resources

import numpy as np

#: each page: its route, title, panel (in rigmap/studio/page, put into ``shell.html``) and
#: script
PAGES = {
    "pose": ("/", "Pose", "pose_panel.html", "pose.js"),
    "play": ("/play", "Play", "play_panel.html", "play.js"),
}
#: what every page loads
SHARED = {"/studio.js": ("studio.js", "text/javascript"), "/studio.css": ("studio.css", "text/css")}
#: a command is a few hundred bytes; anything longer is refused (ours)
MAX_COMMAND_BYTES = 16_384


def encode(header: dict, points=None) -> bytes:
    """One message: header length (uint32 LE), JSON header, zero padding to 4 bytes, then
    ``points`` as float32 (scene units)."""
    text = json.dumps(header, separators=(",", ":")).encode()
    padding = b"\0" * (-(4 + len(text)) % 4)
    data = b"" if points is None else np.ascontiguousarray(points, dtype="<f4").tobytes()
    return len(text).to_bytes(4, "little") + text + padding + data


def decode(message: bytes) -> tuple[dict, np.ndarray]:
    """The header and points of :func:`encode`'s message (what a page reads)."""
    size = int.from_bytes(message[:4], "little")
    start = 4 + size + (-(4 + size) % 4)
    return json.loads(message[4 : 4 + size]), np.frombuffer(message[start:], dtype="<f4")


def served_files(pages) -> dict[str, tuple[bytes, str]]:
    """Route -> (body, content type) for ``pages`` (names of :data:`PAGES`): each page is
    ``shell.html`` with its title, panel and script put in, plus its script and the shared
    files; all read from the package once."""
    folder = resources.files("rigmap.studio").joinpath("page")

    def text(name: str) -> str:
        return folder.joinpath(name).read_text(encoding="utf-8")

    utf8 = "; charset=utf-8"
    files = {route: (text(name).encode(), kind + utf8) for route, (name, kind) in SHARED.items()}
    for name in pages:
        route, title, panel, script = PAGES[name]
        page = text("shell.html").replace("TITLE", title).replace("SCRIPT", script)
        files[route] = (page.replace("PANEL", text(panel)).encode(), "text/html" + utf8)
        files[f"/{script}"] = (text(script).encode(), "text/javascript" + utf8)
    return files


class CommandError(ValueError):
    """A command a page should not have sent: answered with an error, never acted on."""


class Channel:
    """One page's side in Python: :meth:`greeting` for a page that connects, :meth:`command`
    for each command it sends, :meth:`opened` / :meth:`closed` as pages come and go;
    :attr:`broadcast` ``(message, replaceable=False)`` (set by the server) reaches every
    page of the channel (:class:`Outbox`)."""

    def __init__(self):
        self.broadcast = lambda message, replaceable=False: None

    def greeting(self) -> list[bytes]:
        return []

    def opened(self) -> None:
        pass

    def closed(self) -> None:
        pass

    def command(self, command: dict) -> None:
        raise CommandError(f"unknown command {command.get('type')!r}")

    def close(self) -> None:
        pass


def parse_command(message) -> dict:
    """A page's message as a command: a JSON object with a ``type``."""
    if not isinstance(message, str):
        raise CommandError("commands are JSON text")
    try:
        command = json.loads(message)
    except json.JSONDecodeError as error:
        raise CommandError(f"not JSON: {error}") from None
    if not isinstance(command, dict) or not isinstance(command.get("type"), str):
        raise CommandError("a command is a JSON object with a type")
    return command


#: a page's unsent messages beyond which its oldest replaceable one (a pose, a frame) is
#: dropped: a page that stops reading never holds up the posing or Play's clock (ours)
MAX_PENDING = 4


class Outbox:
    """One page's messages, sent in order by a thread of its own. A message marked
    ``replaceable`` (a pose, a frame: a newer one shows all it did) is dropped, oldest first,
    when more than :data:`MAX_PENDING` wait; the others always go."""

    def __init__(self, connection, name: str):
        from websockets.exceptions import ConnectionClosed

        self.connection, self.name = connection, name
        self._closed_error = ConnectionClosed
        self._waiting: deque[tuple[bytes, bool]] = deque()
        self._wake = threading.Condition()
        self._open = True
        self._thread = threading.Thread(target=self._send_loop, name="studio-page-out", daemon=True)
        self._thread.start()

    def put(self, message: bytes, *, replaceable: bool = False) -> None:
        with self._wake:
            self._waiting.append((message, replaceable))
            if len(self._waiting) > MAX_PENDING:
                oldest = next((m for m in self._waiting if m[1]), None)
                if oldest is not None:
                    self._waiting.remove(oldest)
            self._wake.notify()

    def close(self) -> None:
        with self._wake:
            self._open = False
            self._wake.notify()

    def _send_loop(self) -> None:
        while True:
            with self._wake:
                while not self._waiting and self._open:
                    self._wake.wait()
                if not self._open:
                    return
                message, _ = self._waiting.popleft()
            try:
                self.connection.send(message)
            except (self._closed_error, OSError):
                return


class PageServer:
    """``channels`` (a page name, ``pose`` or ``play``, to its :class:`Channel`) served at
    ``host:port`` (``port`` 0: a free one); ``studio_url`` (the viser page) is linked."""

    def __init__(self, channels: dict[str, Channel], *, host: str, port: int):
        from websockets.sync.server import serve

        self.channels = dict(channels)
        self.studio_url: str | None = None
        self._outboxes: dict[object, Outbox] = {}
        self._outboxes_lock = threading.Lock()
        self._files = served_files(self.channels)
        for name, channel in self.channels.items():
            channel.broadcast = partial(self._broadcast, name)
        self._server = serve(
            self._connected,
            host,
            port,
            process_request=self._http,
            compression=None,  # frames go once to a local page: deflate only costs time
            max_size=MAX_COMMAND_BYTES,
            close_timeout=1.0,  # a page that does not answer the close is dropped (ours)
        )
        self.host, self.port = host, self._server.socket.getsockname()[1]
        self._thread = threading.Thread(
            target=self._server.serve_forever, name="studio-pages", daemon=True
        )
        self._thread.start()

    def __getitem__(self, name: str) -> Channel:
        return self.channels[name]

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def routes(self) -> dict[str, str]:
        """Each page's route, by its title."""
        return {PAGES[name][1]: PAGES[name][0] for name in self.channels}

    def links(self) -> dict[str, str]:
        """Each page's address, by its title."""
        return {title: self.url + route for title, route in self.routes().items()}

    def stop(self) -> None:
        """Stop serving and close every open page's connection (its handler thread, which
        the server does not make a daemon, then ends: an open tab never keeps the process)."""
        for channel in self.channels.values():
            channel.close()
        self._server.shutdown()
        self._thread.join(timeout=5)
        with self._outboxes_lock:
            connections = list(self._outboxes)
        for connection in connections:
            connection.close()

    # ------------------------------------------------------------------ http
    def _origins(self) -> set[str]:
        names = {self.host, "localhost"} if self.host == "127.0.0.1" else {self.host}
        return {f"http://{name}:{self.port}" for name in names}

    def _http(self, connection, request):
        from websockets.datastructures import Headers
        from websockets.http11 import Response

        path = request.path.partition("?")[0]
        if request.headers.get("Upgrade", "").lower() == "websocket":
            name = path.removesuffix("/ws").strip("/")
            if not path.endswith("/ws") or name not in self.channels:
                return connection.respond(http.HTTPStatus.NOT_FOUND, f"no websocket at {path}\n")
            origin = request.headers.get("Origin")
            if origin is not None and origin not in self._origins():
                return connection.respond(
                    http.HTTPStatus.FORBIDDEN, f"origin {origin} may not drive this page\n"
                )
            return None
        if path not in self._files:
            return connection.respond(
                http.HTTPStatus.NOT_FOUND,
                f"{path}: not served (the studio's pages serve only {', '.join(self._files)})\n",
            )
        body, kind = self._files[path]
        headers = Headers(
            [
                ("Content-Type", kind),
                ("Content-Length", str(len(body))),
                ("Cache-Control", "no-store"),
                ("X-Content-Type-Options", "nosniff"),
                ("Content-Security-Policy", "default-src 'self'; img-src data:"),
            ]
        )
        return Response(http.HTTPStatus.OK, "OK", headers, body)

    # ------------------------------------------------------------------ websockets
    def _connected(self, connection) -> None:
        name = connection.request.path.partition("?")[0].removesuffix("/ws").strip("/")
        channel = self.channels[name]
        outbox = Outbox(connection, name)
        with self._outboxes_lock:
            self._outboxes[connection] = outbox
        channel.opened()
        try:
            for message in channel.greeting():
                outbox.put(message)
            links = {"type": "links", "pages": self.routes(), "studio": self.studio_url}
            outbox.put(encode(links))
            for message in connection:
                try:
                    channel.command(parse_command(message))
                except CommandError as error:
                    outbox.put(encode({"type": "error", "message": str(error)}))
        finally:
            with self._outboxes_lock:
                self._outboxes.pop(connection, None)
            outbox.close()
            channel.closed()

    def _broadcast(self, name: str, message: bytes, *, replaceable: bool = False) -> None:
        with self._outboxes_lock:
            outboxes = [box for box in self._outboxes.values() if box.name == name]
        for outbox in outboxes:
            outbox.put(message, replaceable=replaceable)
