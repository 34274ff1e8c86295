"""connect() and Client: a channel to a fulcrum-server with the package's defaults."""

import os

import grpc

from .errors import FulcrumError, invalid_argument
from .replays import Replay, verify
from .scenes import to_scene
from . import snapshots
from .snapshots import fnv1a64
from .v1 import runtime_pb2, service_pb2, service_pb2_grpc, stats_pb2
from .world import World, _snapshot_file

# Channel options the package sets (docs/python.md, "Channel options", says why and what other
# gRPC clients should set):
#   * HTTP/2 flow control. gRPC's BDP probe grows a stream's receive window to megabytes on a
#     fast link; the server then writes that far ahead of a slow frame reader, whose frames
#     queue in the window instead of being coalesced on the server, so they arrive seconds
#     old. Without the probe the window stays at lookahead_bytes, 1 KiB: about one frame
#     ahead (a slow reader of the 211-body pyramid read frames 7 ticks old, against 12 with
#     16 KiB and 49 with 64 KiB). A message larger than the window still arrives whole (gRPC
#     opens the window for it): snapshot transfers took as long with 256 bytes as with 64 KiB.
#   * Receive size. gRPC's default 4 MiB limit refuses a snapshot of the large pyramid (5051
#     bodies: 4.49 MB at tick 30); the server enforces its own limits, so the client takes any size
#     (as the C++ client does).
CHANNEL_OPTIONS = (
    ("grpc.http2.bdp_probe", 0),
    ("grpc.http2.lookahead_bytes", 1024),
    ("grpc.max_receive_message_length", -1),
)

DEFAULT_ADDRESS = "127.0.0.1:50051"
DEFAULT_TIMEOUT = 30.0  # s, per unary call (Client(timeout=...), World.step(timeout=...))


def _read(path, what):
    try:
        with open(path, "rb") as source:
            return source.read()
    except OSError as error:
        raise invalid_argument(what, f"{path}: cannot read: {error.strerror}") from None


def _credentials(tls):
    """Channel credentials from `tls`: True (the system's roots), a path to a PEM file of root
    certificates, or the PEM bytes."""
    if tls is True:
        return grpc.ssl_channel_credentials()
    if isinstance(tls, (bytes, bytearray)):
        pem = bytes(tls)
    elif isinstance(tls, (str, os.PathLike)):
        pem = _read(tls, "tls")
    else:
        raise invalid_argument("tls", f"expected True, a PEM file path or PEM bytes, "
                                      f"got {type(tls).__name__}")
    if b"-----BEGIN CERTIFICATE-----" not in pem:
        raise invalid_argument("tls", "holds no PEM certificate")
    return grpc.ssl_channel_credentials(root_certificates=pem)


def connect(address=DEFAULT_ADDRESS, token=None, token_file=None, tls=False, tls_name=None,
            timeout=DEFAULT_TIMEOUT, options=(), wait=None):
    """A Client of the server at `address` ("HOST:PORT"); a context manager that closes it.

    token / token_file: the bearer token of a server started with --token-file (the file's
        first line, as `fulcrum --token-file` reads it).
    tls: False (plaintext), True (TLS, the system's roots), or the root certificate that
        signed the server's (a PEM file path or PEM bytes); tls_name: the name the certificate
        must carry when `address` is an IP ("localhost").
    timeout: seconds per unary call (None: no deadline).
    options: more gRPC channel options, after (and so overriding) CHANNEL_OPTIONS.
    wait: seconds to wait for the connection before returning (None: connect lazily, so a
        server that is down shows up as UNAVAILABLE on the first call).
    """
    return Client(address, token=token, token_file=token_file, tls=tls, tls_name=tls_name,
                  timeout=timeout, options=options, wait=wait)


class Client:
    """A connection to one fulcrum-server. See connect()."""

    def __init__(self, address=DEFAULT_ADDRESS, token=None, token_file=None, tls=False,
                 tls_name=None, timeout=DEFAULT_TIMEOUT, options=(), wait=None):
        if token is not None and token_file is not None:
            raise invalid_argument("token_file", "give token or token_file, not both")
        if token_file is not None:
            text = _read(token_file, "token_file").decode("utf-8", "replace")
            token = text.splitlines()[0] if text else ""
        self.address = address
        self.timeout = timeout
        self._metadata = (("authorization", f"Bearer {token}"),) if token else ()
        # gRPC core reads the first of two equal keys, so `options` replace the defaults here.
        merged = dict(CHANNEL_OPTIONS)
        merged.update(dict(options))
        if tls_name:
            if not tls:
                raise invalid_argument("tls_name", "needs tls")
            merged["grpc.ssl_target_name_override"] = tls_name
        channel_options = list(merged.items())
        if tls:
            self.channel = grpc.secure_channel(address, _credentials(tls), channel_options)
        else:
            self.channel = grpc.insecure_channel(address, channel_options)
        self._stub = service_pb2_grpc.PhysicsStub(self.channel)
        if wait is not None:
            try:
                grpc.channel_ready_future(self.channel).result(timeout=wait)
            except grpc.FutureTimeoutError:
                self.channel.close()
                raise FulcrumError(grpc.StatusCode.UNAVAILABLE,
                                   f"no server at {address} after {wait} s") from None

    def __repr__(self):
        return f"fulcrum.Client({self.address!r})"

    def close(self):
        """Closes the channel; open frame streams end."""
        self.channel.close()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, traceback):
        self.close()
        return False

    # --- Calls: the one place server errors become FulcrumError ------------------------------

    def _call(self, method, request, timeout=None):
        try:
            return getattr(self._stub, method)(
                request, timeout=timeout if timeout is not None else self.timeout,
                metadata=self._metadata)
        except grpc.RpcError as error:
            raise FulcrumError.from_rpc(error) from None

    def _stream(self, method, request, timeout=None):
        """A server-streaming call; its errors surface when it is read (FrameStream)."""
        return getattr(self._stub, method)(request, timeout=timeout, metadata=self._metadata)

    # --- Worlds -------------------------------------------------------------------------------

    def create_world(self, scene, name=None):
        """A new world from a scene: a dict (scene JSON form), a JSON file path, or a
        fulcrum.v1.Scene. `name` replaces the scene's name. Returns a World."""
        scene = to_scene(scene)
        if name is not None:
            named = type(scene)()
            named.CopyFrom(scene)
            named.name = name
            scene = named
        reply = self._call("CreateWorld", service_pb2.CreateWorldRequest(scene=scene))
        return World(self, reply.world_id)

    def world(self, world_id):
        """The World with this id (no call: a world that does not exist shows up as NOT_FOUND
        on the first call)."""
        return World(self, int(world_id))

    def worlds(self):
        """Every world on the server, as fulcrum.v1.WorldInfo (settings left out), by id."""
        return list(self._call("ListWorlds", service_pb2.ListWorldsRequest()).worlds)

    def fork(self, snapshot, name="fork"):
        """A new world from a Snapshot (or snapshot file bytes)."""
        reply = snapshots.upload(self, 0, _snapshot_file(snapshot), name or "")
        return World(self, reply.world_id)

    def stats(self):
        """The server's counters (a fulcrum.v1.ServerStats)."""
        return self._call("GetStats", stats_pb2.GetStatsRequest())

    # --- Replays ------------------------------------------------------------------------------

    def download_replay(self, name, path=None):
        """A replay recorded on the server, by name ("world1-1.replay"), as a Replay (saved to
        `path` too when given). Its size and checksum are checked (DATA_LOSS if they differ)."""
        return self._download(runtime_pb2.DownloadReplayRequest(name=name), path)

    def _download(self, request, path):
        parts = []
        received = 0
        name, total, checksum = "", None, None
        try:
            for chunk in self._stub.DownloadReplay(request, timeout=self.timeout,
                                                   metadata=self._metadata):
                if total is None:
                    name, total = chunk.name, chunk.total_size
                if chunk.offset != received:
                    raise FulcrumError(grpc.StatusCode.DATA_LOSS, f"replay {name}: chunk at "
                                       f"offset {chunk.offset}, expected {received}")
                parts.append(chunk.data)
                received += len(chunk.data)
                if chunk.last:
                    checksum = chunk.checksum
        except grpc.RpcError as error:
            raise FulcrumError.from_rpc(error) from None
        data = b"".join(parts)
        if checksum is None or len(data) != total:
            raise FulcrumError(grpc.StatusCode.DATA_LOSS,
                               f"replay {name}: received {len(data)} of {total} bytes")
        if fnv1a64(data) != checksum:
            raise FulcrumError(grpc.StatusCode.DATA_LOSS,
                               f"replay {name}: checksum mismatch with the server's")
        replay = Replay.from_bytes(data, where=f"replay {name}", name=name)
        if path is not None:
            replay.save(path)
        return replay

    def verify_replay(self, replay):
        """Re-simulates a Replay (or a replay file path) on this server, in a temporary world,
        tick by tick; returns a ReplayReport (ok, ticks, final_tick, final_hash, diverged_at,
        detail)."""
        if isinstance(replay, (str, os.PathLike)):
            replay = Replay.load(replay)
        return verify(self, replay)
