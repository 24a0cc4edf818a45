"""`servo view` (the Foxglove live view) against the recording of the same run: a WebSocket
client speaking the Foxglove WebSocket protocol (foxglove.websocket.v1) subscribes to /overview, sets the gain_scale parameter
(the controller must apply it) and stops the run through the stop service; the samples it
received equal the recording's /overview (the same bins), and the run ended by that stop."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

websockets_sync = pytest.importorskip("websockets.sync.client")
from websockets.exceptions import ConnectionClosed  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SERVO = os.environ.get("FTS_SERVO_BIN", str(ROOT / "target" / "release" / "servo"))
SUBPROTOCOL = "foxglove.websocket.v1"  # the protocol's own name (the view also serves foxglove.sdk.v1)


def spawn(*args: str, **kw) -> subprocess.Popen:
    return subprocess.Popen([SERVO, *args], **kw)


class Client:
    """The few foxglove.websocket.v1 operations the test needs."""

    def __init__(self, ws) -> None:
        self.ws = ws
        self.channels: dict = {}
        self.services: dict = {}
        self.overview: list = []
        self.parameters: dict = {}
        self.service_responses: list = []
        self.stopped_at = None

    def handle(self, raw) -> None:
        if isinstance(raw, str):
            msg = json.loads(raw)
            if msg["op"] == "advertise":
                self.channels.update({c["topic"]: c for c in msg["channels"]})
            elif msg["op"] == "advertiseServices":
                self.services.update({s["name"]: s for s in msg["services"]})
            elif msg["op"] == "parameterValues":
                self.parameters[msg.get("id")] = msg["parameters"]
            return
        if raw[0] == 0x01:  # message data: subscription id, log time, payload
            _, log_time = struct.unpack_from("<IQ", raw, 1)
            self.overview.append((log_time, json.loads(raw[13:])))
        elif raw[0] == 0x03:  # service call response
            service, call, n = struct.unpack_from("<III", raw, 1)
            self.service_responses.append((call, raw[13 + n :]))

    def pump(self, until, timeout_s: float = 60.0) -> None:
        deadline = time.monotonic() + timeout_s
        while not until():
            assert time.monotonic() < deadline, "timed out waiting on the live view"
            self.handle(self.ws.recv(timeout=timeout_s))

    def send(self, op: dict) -> None:
        self.ws.send(json.dumps(op))


def recorded_overview(path: Path) -> list:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        return [(m.log_time, msg) for _, _, m, msg in reader.iter_decoded_messages(topics=["/overview"])]


def test_the_live_view_shows_the_recorded_bins_and_steers_the_run(tmp_path: Path) -> None:
    prefix = f"pytest-view-{os.getpid()}"
    rec = tmp_path / "run.mcap"
    common = ["--prefix", prefix]
    plant = spawn("plant", *common, "--duration", "120", "--wait-start")
    controller = spawn("controller", *common, stdout=subprocess.DEVNULL)
    recorder = spawn("record", *common, "-q", "--json", "--out", str(rec), stdout=subprocess.PIPE)
    view = spawn("view", *common, "--port", "0", stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = view.stdout.readline().strip()
        assert url.startswith("ws://127.0.0.1:"), url
        with websockets_sync.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
            client = Client(ws)
            steer(client, common)
        assert plant.wait(60) == 0 and controller.wait(60) == 0
        summary = json.loads(recorder.communicate(timeout=60)[0])
        assert view.wait(60) == 0, view.stderr.read()
    finally:
        for p in (plant, controller, recorder, view):
            if p.poll() is None:
                p.kill()
    # The run was stopped by the service (far short of its 120 s).
    assert summary["ticks"] <= client.stopped_at + 2048 and summary["ticks"] < 120 * 199_600
    # The live bins are the recording's: same count, times and values.
    recorded = recorded_overview(rec)
    live = client.overview
    assert len(live) == len(recorded) > 100
    t0 = recorded[0][0] - live[0][0]
    for (t_live, ours), (t_rec, theirs) in zip(live, recorded):
        assert t_rec - t0 == t_live
        assert ours["ticks"] == theirs.ticks
        for group in ("min", "max", "mean"):
            for field, value in ours[group].items():
                assert np.float32(value) == np.float32(getattr(getattr(theirs, group), field)), (group, field)


def steer(client: Client, common: list) -> None:
    """Subscribes, checks the metadata, starts the run, sets two gains, stops it, and reads
    until the view closes the connection after the run."""
    client.pump(lambda: "/overview" in client.channels and "stop" in client.services)
    channel = client.channels["/overview"]
    assert channel["encoding"] == "json" and channel["schemaEncoding"] == "jsonschema"
    client.send({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channel["id"]}]})
    client.send({"op": "getParameters", "parameterNames": [], "id": "meta"})
    client.pump(lambda: "meta" in client.parameters)
    meta = {p["name"]: p["value"] for p in client.parameters["meta"]}
    assert meta["gain_scale"] == 1.0
    started = subprocess.run([SERVO, "ctl", *common, "start"], capture_output=True, text=True)
    assert started.returncode == 0, started.stderr
    # A tenth of a second of run, then a gain the loop can take: the controller applies it.
    client.pump(lambda: len(client.overview) >= 100)
    gain = {"name": "gain_scale", "value": 1.2, "type": "float64"}
    client.send({"op": "setParameters", "id": "gain", "parameters": [gain]})
    client.pump(lambda: "gain" in client.parameters)
    assert client.parameters["gain"] == [{"name": "gain_scale", "type": "float64", "value": 1.2}]
    # Then a gain beyond its margin: refused, the parameter keeps the applied value.
    wild = {"name": "gain_scale", "value": 50.0, "type": "float64"}
    client.send({"op": "setParameters", "id": "wild", "parameters": [wild]})
    client.pump(lambda: "wild" in client.parameters)
    assert client.parameters["wild"][0]["value"] == 1.2
    # Stop through the service (binary service call: id, call id, encoding, payload).
    stop = client.services["stop"]
    client.ws.send(struct.pack("<BIII", 0x02, stop["id"], 1, len(b"json")) + b"json{}")
    client.pump(lambda: client.service_responses)
    client.stopped_at = json.loads(client.service_responses[0][1])["stopped_at_tick"]
    with pytest.raises(ConnectionClosed):
        client.pump(lambda: False, timeout_s=30)


def test_a_view_beyond_loopback_speaks_tls_to_a_pinned_certificate(tmp_path: Path) -> None:
    """Beyond loopback the view serves wss:// with a self-signed certificate made on first use
    (in XDG_CONFIG_HOME) and prints its SHA-256 fingerprint after the URL. Python's ssl pins it:
    the certificate fetched, its fingerprint compared with the printed one, then trusted alone.
    With the token forty clients in a row each read the server's info; a wrong token is refused
    (401, inside TLS); a cleartext client gets no WebSocket handshake."""
    import hashlib
    import ssl

    from websockets.exceptions import InvalidStatus

    env = dict(os.environ, XDG_CONFIG_HOME=str(tmp_path))
    prefix = f"pytest-tls-{os.getpid()}"
    view = spawn("view", "--prefix", prefix, "--host", "0.0.0.0", "--port", "0",
                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        url, pin = view.stdout.readline().strip(), view.stdout.readline().strip()
        assert url.startswith("wss://0.0.0.0:") and pin.startswith("sha256 "), (url, pin)
        port = int(url.split(":")[2].split("/")[0])
        token = url.split("?token=")[1]
        pem = ssl.get_server_certificate(("127.0.0.1", port))
        fingerprint = hashlib.sha256(ssl.PEM_cert_to_DER_cert(pem)).hexdigest().upper()
        assert ":".join(fingerprint[i : i + 2] for i in range(0, 64, 2)) == pin.split()[1]
        pinned = ssl.create_default_context(cadata=pem)
        pinned.check_hostname = False  # the fingerprint is the identity, not a name
        local = f"wss://127.0.0.1:{port}/"
        # Clients one after another, each answered at once (this client reads and writes its TLS
        # connection from two threads: a session ticket sent mid-request used to stall about one
        # in twenty until the view's 5 s handshake limit closed it).
        for _ in range(40):
            with websockets_sync.connect(f"{local}?token={token}", ssl=pinned, subprotocols=[SUBPROTOCOL]) as ws:
                assert json.loads(ws.recv(timeout=30))["op"] == "serverInfo"
        with pytest.raises(InvalidStatus) as refused:
            websockets_sync.connect(f"{local}?token={'0' * 32}", ssl=pinned, subprotocols=[SUBPROTOCOL])
        assert refused.value.response.status_code == 401
        with pytest.raises(Exception) as cleartext:
            websockets_sync.connect(f"ws://127.0.0.1:{port}/?token={token}", subprotocols=[SUBPROTOCOL],
                                    open_timeout=20)
        assert not isinstance(cleartext.value, InvalidStatus), "a cleartext client got an HTTP answer"
    finally:
        view.terminate()
        view.wait(30)
