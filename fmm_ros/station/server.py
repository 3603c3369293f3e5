"""The station's web server: the page, its event stream, and the operator's two forms.

tornado (pinned already: dask.distributed's own server) runs on its own thread and event loop
beside the node's executor. The page (static/, uPlot vendored beside it: no CDN, it works
offline) opens `/events`, a server-sent event stream: first a `snapshot` of everything, then
each change as it happens; the browser's EventSource reconnects by itself when the station
restarts, and gets a fresh snapshot. A client that cannot keep up (its queue of
`CLIENT_QUEUE` events is full) is closed: it reconnects and starts from a snapshot, so the
server never buffers without bound and nothing the rig recorded depends on a browser.

Two JSON endpoints take the operator's input: POST /api/judge (a decision about a hit) and
POST /api/session (the session's metadata). Bad input gets 400 and a message naming the
problem, which the page shows; the node logs it. Only `application/json` is taken, so a
page of another site cannot post a plain form to the station.
"""

from __future__ import annotations

import asyncio
import json
import threading
from collections.abc import Callable
from pathlib import Path

import tornado.httpserver
import tornado.netutil
import tornado.web
from tornado.iostream import StreamClosedError

from fmm_ros.errors import FmmError

STATIC = Path(__file__).parent / 'static'
CLIENT_QUEUE = 256
"""Events queued for one page before it is dropped (and reconnects) [-]."""
RETRY_MS = 1000
"""How soon a page retries after the stream ended (the station restarted) [ms]."""
KEEPALIVE_S = 15.0
"""A comment line this often keeps proxies and the browser from timing the stream out [s]."""

Handler = Callable[[dict], str]
"""An endpoint's action: takes the JSON body, returns a message; FmmError refuses it."""


def event_text(name: str, payload: object) -> str:
    """One server-sent event (strict JSON: a NaN is a bug here, the browser cannot parse it)."""
    data = json.dumps(payload, separators=(',', ':'), allow_nan=False)
    return f'event: {name}\ndata: {data}\n\n'


class Hub:
    """The connected pages: each has a queue of event texts, filled from any thread."""

    def __init__(self) -> None:
        self.loop: asyncio.AbstractEventLoop | None = None
        self.clients: set[asyncio.Queue] = set()
        self.dropped = 0

    def broadcast(self, name: str, payload: object) -> None:
        """Send an event to every page (thread-safe; serialized once)."""
        if self.loop is None or not self.clients:
            return
        text = event_text(name, payload)
        self.loop.call_soon_threadsafe(self._fan_out, text)

    def _fan_out(self, text: str) -> None:
        for queue in list(self.clients):
            try:
                queue.put_nowait(text)
            except asyncio.QueueFull:
                self.dropped += 1
                end(queue)  # the handler ends the response; the page reconnects


def end(queue: asyncio.Queue) -> None:
    """Tell a page's handler to end its stream: whatever was queued is dropped."""
    while not queue.empty():
        queue.get_nowait()
    queue.put_nowait(None)


class EventsHandler(tornado.web.RequestHandler):
    """GET /events: the server-sent event stream of one page."""

    def initialize(self, hub: Hub, snapshot: Callable[[], dict]) -> None:
        """Tornado's constructor hook: the hub to join and where snapshots come from."""
        self.hub = hub
        self.snapshot = snapshot
        self.queue: asyncio.Queue | None = None

    async def get(self) -> None:
        """The snapshot, then every event, until the page or the server goes."""
        self.set_header('Content-Type', 'text/event-stream')
        self.set_header('Cache-Control', 'no-cache')
        self.queue = asyncio.Queue(CLIENT_QUEUE)
        self.hub.clients.add(self.queue)
        try:
            self.write(f'retry: {RETRY_MS}\n\n' + event_text('snapshot', self.snapshot()))
            await self.flush()
            while True:
                try:
                    text = await asyncio.wait_for(self.queue.get(), KEEPALIVE_S)
                except TimeoutError:
                    text = ': keepalive\n\n'
                if text is None:
                    break
                self.write(text)
                await self.flush()
        except StreamClosedError:
            pass
        finally:
            self.hub.clients.discard(self.queue)

    def on_connection_close(self) -> None:
        """The page went (closed, reloaded): its queue leaves the hub."""
        if self.queue is not None:
            self.hub.clients.discard(self.queue)
            end(self.queue)


class ActionHandler(tornado.web.RequestHandler):
    """POST of a JSON object to an action; 400 with the reason when it is refused."""

    def initialize(self, action: Handler, log: Callable[[str], None]) -> None:
        """Tornado's constructor hook: the action, and where refusals are logged."""
        self.action = action
        self.log = log

    def post(self) -> None:
        """Check the request is a JSON object, run the action, answer {ok, message}."""
        content_type = self.request.headers.get('Content-Type', '').split(';')[0].strip()
        try:
            if content_type != 'application/json':
                raise FmmError(f'send application/json, not {content_type or "nothing"}')
            try:
                body = json.loads(self.request.body or b'null')
            except (json.JSONDecodeError, UnicodeDecodeError) as error:
                raise FmmError(f'the request is not JSON: {error}') from None
            if not isinstance(body, dict):
                raise FmmError('the request is not a JSON object')
            message = self.action(body)
        except FmmError as error:
            self.log(f'{self.request.path} refused: {error}')
            self.set_status(400)
            self.write({'ok': False, 'message': str(error)})
            return
        self.write({'ok': True, 'message': message})


class StationServer:
    """The page's server on host:port (port 0: any free one), on a thread of its own."""

    def __init__(
        self,
        host: str,
        port: int,
        snapshot: Callable[[], dict],
        actions: dict[str, Handler],
        log: Callable[[str], None],
    ) -> None:
        self.hub = Hub()
        self.host = host
        self.port = port
        self._snapshot = snapshot
        self._actions = actions
        self._log = log
        self._server: tornado.httpserver.HTTPServer | None = None
        self._thread: threading.Thread | None = None
        self._started = threading.Event()
        self._error: BaseException | None = None

    @property
    def url(self) -> str:
        """Where the page is."""
        return f'http://{self.host}:{self.port}/'

    def start(self) -> None:
        """Serve on a thread; return once listening (OSError when it cannot listen)."""
        self._started.clear()
        self._error = None
        self._thread = threading.Thread(target=self._run, name='station_http', daemon=True)
        self._thread.start()
        self._started.wait()
        if self._error is not None:
            self._thread.join()
            raise self._error

    def _run(self) -> None:
        asyncio.run(self._serve())

    async def _serve(self) -> None:
        routes = [
            (r'/events', EventsHandler, {'hub': self.hub, 'snapshot': self._snapshot}),
            *[
                (f'/api/{name}', ActionHandler, {'action': action, 'log': self._log})
                for name, action in self._actions.items()
            ],
            (
                r'/(.*)',
                tornado.web.StaticFileHandler,
                {'path': str(STATIC), 'default_filename': 'index.html'},
            ),
        ]
        try:
            sockets = tornado.netutil.bind_sockets(self.port, self.host)
        except OSError as error:
            self._error = error
            self._started.set()
            return
        self._server = tornado.httpserver.HTTPServer(tornado.web.Application(routes))
        self._server.add_sockets(sockets)
        self.port = sockets[0].getsockname()[1]
        self.hub.loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        self._started.set()
        await self._stop.wait()
        for queue in list(self.hub.clients):
            end(queue)
        self._server.stop()
        await asyncio.sleep(0.05)

    def stop(self) -> None:
        """Stop serving (pages see the stream end and retry) and join the thread."""
        if self.hub.loop is not None and self._thread is not None:
            self.hub.loop.call_soon_threadsafe(self._stop.set)
            self._thread.join(timeout=5.0)
        self.hub.loop = None
