"""The studio's server: one viser scene, a menu of views, the folders it may touch, and
links to the pages served beside it.

viser for Review, Edit and Play: a maintained three.js client with transform gizmos, GUI
widgets and a websocket to Python, so the views are Python that calls rigmap directly. Pose
and Play have pages of their own (:mod:`.page_server`: a drag or a frame must reach the
screen faster than viser's client passes updates on), linked from the studio's panel.
"""

from __future__ import annotations

import threading

from rigmap.studio.scene import light_for_software_rendering

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8080


class Studio:
    """``views`` (objects with ``name``, ``build(server, gui)``, ``show(visible)``,
    ``close()``) on one server; the ``View`` menu shows one at a time. ``pages`` (a
    :class:`~rigmap.studio.page_server.PageServer`, or None) serves the studio's own pages:
    linked from the panel, and stopped with it."""

    def __init__(self, views, *, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, pages=None):
        import viser

        if not views:
            raise ValueError("the studio needs at least one view")
        self.views = {view.name: view for view in views}
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.server.scene.set_up_direction("+y")
        light_for_software_rendering(self.server.scene)
        self.server.gui.configure_theme(control_width="large", show_share_button=False)
        self.host, self.port = host, self.server.get_port()
        gui = self.server.gui
        self.pages = pages
        for name, url in ({} if pages is None else pages.links()).items():
            gui.add_markdown(f"**{name}** has its own page: [{url}]({url})")
        self.menu = gui.add_dropdown("View", options=list(self.views))
        self.folders = {}
        for name, view in self.views.items():
            folder = gui.add_folder(name)
            with folder:
                view.build(self.server, gui)
            self.folders[name] = folder
        self.menu.on_update(lambda _event: self.switch(self.menu.value))
        self.switch(self.menu.value)
        self._stopped = threading.Event()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def switch(self, name: str) -> None:
        for other, view in self.views.items():
            visible = other == name
            self.folders[other].visible = visible
            view.show(visible)

    def wait(self) -> None:
        """Serve until interrupted (Ctrl-C) or :meth:`stop`."""
        try:
            self._stopped.wait()
        except KeyboardInterrupt:
            pass
        self.stop()

    def stop(self) -> None:
        for view in self.views.values():
            view.close()
        if self.pages is not None:
            self.pages.stop()
        self.server.stop()
        self._stopped.set()
