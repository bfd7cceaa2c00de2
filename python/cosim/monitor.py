"""Watching a run: the messages of its monitor bus, decoded.

    for msg in cosim.Monitor("runs/default", topics=["coupler.traction"]):
        print(msg.step, msg.row["T_H"])

The bus drops messages for a subscriber that lags by more than its queues
(the scene's ``bus.hwm`` and this monitor's ``hwm``): a monitor never slows
a run. One that joins late sees what is published after its subscription
reaches the coupler.
"""
import json
import os
import time
import warnings

import zmq

from . import protocol as P
from .errors import CosimError, ProtocolError

ENDPOINTS_FILE = "endpoints.json"
EP_BUS, EP_PID = "bus_monitor", "pid"
EP_SNAPSHOTS = "bus_snapshots"        # the snapshot stream, when the run has one
EP_KEY_FILE = "monitor_key_file"      # with security.curve: the monitors' CURVE keys
POLL_MS = 100
END_GRACE_S = 0.5  # after the last step: what participants publish still arrives
# Given a bus endpoint (no run to watch), the run is taken as ended when the
# bus, whose coupler.progress comes about twice a second while the run steps,
# has been silent for this long after a message came: a subscriber that misses
# the last progress (dropped at the high-water mark, or sent as the bus
# closed) does not wait for ever. Any message, not only a progress, starts
# the clock: one that joins a short run after its last periodic progress
# (a stub run of a second or two on a loaded machine) sees only rows.
PROGRESS_LOST_S = 20.0
DEFAULT_HWM = 10000


def _alive(pid):
    try:
        os.kill(pid, 0)
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def run_endpoint(output_dir, wait):
    """The run's endpoints.json (bus_monitor, pid, and when the run has them
    bus_snapshots, monitor_key_file), waiting up to ``wait`` seconds for a
    live run to write it."""
    path = os.path.join(output_dir, ENDPOINTS_FILE)
    until = time.monotonic() + wait
    why = "does not exist"
    while True:
        try:
            with open(path) as f:
                ep = json.load(f)
            bus, pid = ep.get(EP_BUS), ep.get(EP_PID)
            if not bus:
                raise CosimError(f"{path}: the run has no monitor bus (bus.monitor)")
            if pid is None or _alive(int(pid)):
                return ep
            why = f"names a run (pid {pid}) that has ended"
        except (OSError, ValueError):
            pass
        if time.monotonic() > until:
            raise CosimError(f"{path} {why} (waited {wait:g} s): is '{output_dir}' the "
                             f"output.dir of a running scene?")
        time.sleep(0.05)


class Monitor:
    """An iterator of :class:`cosim.Message` (topic, header, arrays) from a
    run's bus.

    source   the bus endpoint (``tcp://127.0.0.1:PORT``), or a run's output
             dir: its endpoints.json (waited for up to ``wait`` s) gives the
             endpoints (the monitor stream, and the snapshot stream and the
             CURVE key file when the run has them), and the iteration ends
             when that run has ended
    topics   topic prefixes to receive (default: all), e.g.
             ["coupler.traction", "dem.series"]
    timeout  end the iteration after this many seconds without a message
             (default: never; a run's end still ends it)
    hwm      messages this monitor queues before the bus drops for it
    key_file the monitors' CURVE key file of a run with security.curve (from
             an output dir's endpoints.json it is found by itself)
    progress_lost  given an endpoint: seconds without a message (progress or
             a wanted topic), once one came, that end the iteration
             (default PROGRESS_LOST_S)

    The iteration also ends after the run's last step (its final
    ``coupler.progress``), once the bus has been quiet for a moment; given an
    endpoint, also when the bus, once heard, is silent for ``progress_lost`` s.
    """

    def __init__(self, source, topics=None, timeout=None, hwm=DEFAULT_HWM, wait=10.0,
                 key_file=None, progress_lost=PROGRESS_LOST_S):
        self.pid, endpoints = None, [source]
        if "://" not in source:
            ep = run_endpoint(source, wait)
            self.pid, key_file = ep.get(EP_PID), key_file or ep.get(EP_KEY_FILE)
            endpoints = [ep[EP_BUS]] + ([ep[EP_SNAPSHOTS]] if ep.get(EP_SNAPSHOTS) else [])
        self.endpoint = endpoints[0]
        if isinstance(topics, str):
            topics = [topics]
        self.topics = list(topics or [""])
        self.timeout = timeout
        self.malformed = 0  # messages that broke the framing (skipped)
        self._ended = None  # when the end of the run was seen
        self._heard = None  # when the last message (of any topic) came
        self._lost = progress_lost
        self._ctx = zmq.Context()
        self._sub = self._ctx.socket(zmq.SUB)
        self._sub.setsockopt(zmq.RCVHWM, hwm)
        self._sub.setsockopt(zmq.LINGER, 0)
        for t in set(self.topics) | {P.TOPIC_PROGRESS}:
            self._sub.setsockopt(zmq.SUBSCRIBE, t.encode())
        if key_file:
            P.curve_client([self._sub], key_file)
        for ep in endpoints:  # one SUB may connect to both streams
            self._sub.connect(ep)

    def __iter__(self):
        return self

    def _wanted(self, topic):
        return any(topic.startswith(t) for t in self.topics)

    def _run_over(self):
        if self._ended is None and self.pid is not None and not _alive(int(self.pid)):
            self._ended = time.monotonic()
        if (self._ended is None and self.pid is None and self._heard is not None and
                time.monotonic() - self._heard > self._lost):
            self._ended = time.monotonic() - END_GRACE_S
        return self._ended is not None and time.monotonic() - self._ended > END_GRACE_S

    def __next__(self):
        if self._sub.closed:
            raise StopIteration
        quiet_since = time.monotonic()
        while True:
            if not self._sub.poll(POLL_MS):
                now = time.monotonic()
                if self._run_over() or (self.timeout is not None and
                                        now - quiet_since > self.timeout):
                    self.close()
                    raise StopIteration
                continue
            try:
                m = P.decode(self._sub.recv_multipart(copy=False))
            except ProtocolError as e:
                self.malformed += 1
                warnings.warn(f"cosim.Monitor: skipped a malformed message: {e}")
                continue
            self._heard = time.monotonic()
            if m.topic == P.TOPIC_PROGRESS:
                n = m.header.get(P.H_N_STEPS)
                if isinstance(n, (int, float)) and m.step >= n:
                    self._ended = time.monotonic()
            if self._ended is not None:
                self._ended = time.monotonic()  # quiet is measured from the last message
            if self._wanted(m.topic):
                return m

    def close(self):
        if not self._sub.closed:
            self._sub.close()
            self._ctx.term()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
