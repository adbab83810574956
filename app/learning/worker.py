"""The learner in its own process, with a request/response interface (docs/learning.md).

A GP fit holds the GIL for tens to hundreds of milliseconds, which would starve a 500 Hz control
loop in the same process, so the learner runs in a worker process (torch lives only there,
single-threaded). Workers are forked from a ``forkserver`` that has imported the learner (torch,
GPyTorch, BoTorch) once: a participant's learner, a resumed one or a restarted one starts in a
fraction of a second instead of importing them afresh (about 3 s of CPU each). The caller's side,
:class:`LearnerClient`, imports no torch::

    client = LearnerClient(LearnerConfig(box=ParameterBox.from_bounds(THETA_BOUNDS), seed=7))
    client.submit()                        # ask for the first θ
    suggestion = client.get(timeout=2.0)   # Suggestion; a flagged fallback if the worker is late
    ...run the handover, collect the placement...
    client.submit([Interaction(interaction_id="1", theta=suggestion.theta)], comparisons)
    client.pending                         # True until the reply has arrived (non-blocking)
    client.poll()                          # the reply if it has arrived, else None
    client.best                            # the recommended θ* from the latest reply
    client.incumbent                       # the batch-opening θ* (an observed point)
    client.state                           # the worker's exact LearnerSnapshot, for storage
    client.settledness                     # the stopping signal, after a batch (else None)
    client.close()

Fallback: when ``get`` times out, the caller receives a Sobol point of the box (or the last known
batch-opening θ* if the schedule's slot is θ*), flagged ``fallback=True``; the learner keeps its state and the
late reply is dropped. Crashes: a dead worker is detected on ``pending``/``poll``/``get`` and
restarted with the full history replayed (one fit), up to ``max_restarts`` times; after that
:class:`WorkerError` is raised.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import multiprocessing as mp
import threading
import time
from multiprocessing.connection import Connection
from multiprocessing.context import ForkContext, ForkServerContext, SpawnContext
from typing import Any, cast

from pydantic import BaseModel, ConfigDict

from app.learning.config import LearnerConfig, LearnerSnapshot
from app.learning.errors import LearningError, WorkerError
from app.learning.models import (
    BestPoint,
    Comparison,
    Interaction,
    NextBatchGain,
    PosteriorSlice,
    Settledness,
    SlotKind,
    Suggestion,
)
from app.learning.rng import derive_seed
from robot_io.child_signals import ignore_interrupts, interrupts_held

logger = logging.getLogger(__name__)

#: How often a waiting ``get`` checks that the worker is still alive (s).
_LIVENESS_PERIOD = 0.2
#: How workers are started: forked from a server process that imported :data:`PRELOAD` once.
START_METHOD = "forkserver"
#: What the forkserver imports before it forks the first worker (app.learning.forkserver_preload):
#: the learner and, through it, torch, GPyTorch and BoTorch; and the module torch imports at a
#: process's first GP fit (``torch.broadcast_shapes`` → symbolic shapes → sympy, 0.8 CPU-s), which
#: every worker would otherwise import again; the forkserver dies with its parent while it imports.
#: The server computes nothing, so no thread pool exists to be forked.
PRELOAD = ["app.learning.forkserver_preload"]


class ObserveRequest(BaseModel):
    """New interactions and the comparisons their placements produced; reply: the next θ."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    request_id: int
    interactions: list[Interaction] = []
    comparisons: list[Comparison] = []


class WorkerReply(BaseModel):
    """The worker's answer to one request: a suggestion, or the error the request caused."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    request_id: int
    suggestion: Suggestion | None = None
    best: BestPoint | None = None
    #: the batch-opening θ* (in-sample incumbent), which a late reply's fallback shows on a θ* slot
    incumbent: dict[str, float] | None = None
    state: LearnerSnapshot | None = None
    slices: list[PosteriorSlice] = []
    #: the stopping signal (app.learning.settled) when the next slot opens a batch or ends learning
    settledness: Settledness | None = None
    #: what the next batch may gain over θ* (app.learning.gain), at the same times, when the
    #: learner's config asks for it (``expected_gain``)
    gain: NextBatchGain | None = None
    error: str | None = None


def _next_request(requests: Connection) -> dict[str, Any] | None:
    """The next request; None to stop, also when the caller's end of the pipe has closed or the
    parent process has died (e.g. SIGKILL)."""
    while True:
        try:
            if requests.poll(_LIVENESS_PERIOD):
                return requests.recv()
        except (EOFError, OSError):
            return None
        parent = mp.parent_process()
        if parent is not None and not parent.is_alive():
            return None


def _serve(config_json: str, snapshot_json: str | None, replay: list[dict[str, Any]],
           requests: Connection, replies: Connection) -> None:  # pragma: no cover - child process
    """Worker process: rebuild the learner (an exact snapshot, then earlier requests replayed),
    then answer requests. Ctrl-C in the application's terminal reaches this process too (its
    process group): it is ignored, and the application ends the worker (its pipe closes)."""
    ignore_interrupts()
    import torch

    from app.learning.learner import PreferenceLearner

    torch.set_num_threads(1)
    if snapshot_json is None:
        learner = PreferenceLearner(LearnerConfig.model_validate_json(config_json))
    else:
        learner = PreferenceLearner.restore(LearnerSnapshot.model_validate_json(snapshot_json))
    earlier = [ObserveRequest.model_validate(r) for r in replay]
    if earlier:
        learner.observe_many([i for r in earlier for i in r.interactions],
                             [c for r in earlier for c in r.comparisons])
    while (message := _next_request(requests)) is not None:
        request = ObserveRequest.model_validate(message)
        try:
            learner.observe_many(request.interactions, request.comparisons)
            suggestion = learner.suggest()
            batch_done = suggestion.slot.kind in (SlotKind.BEST, SlotKind.DONE)
            reply = WorkerReply(request_id=request.request_id, suggestion=suggestion,
                                best=learner.best(), incumbent=learner.incumbent(),
                                state=learner.snapshot(),
                                slices=learner.posterior_slices(),
                                settledness=learner.settledness() if batch_done else None,
                                gain=learner.expected_gain() if batch_done
                                and learner.config.expected_gain else None)
        except LearningError as exc:
            reply = WorkerReply(request_id=request.request_id, error=str(exc))
        try:
            replies.send(reply.model_dump(mode="json"))
        except OSError:  # the caller's end has closed: nobody waits for a reply
            return


def _ready() -> None:  # pragma: no cover - child process
    """The child of :func:`warm_up`: proof that the forkserver serves."""


def _context(start_method: str) -> ForkContext | ForkServerContext | SpawnContext:
    """The :mod:`multiprocessing` context of ``start_method`` (``get_context`` is typed as returning
    the base class, which has no ``Process``, for a method name that is not a literal)."""
    return cast(ForkContext | ForkServerContext | SpawnContext, mp.get_context(start_method))


def warm_up(start_method: str = START_METHOD) -> threading.Thread:
    """Have this process's learner forkserver import :data:`PRELOAD` now, in the background, so
    that the session's first learner forks at once instead of waiting for the imports (several
    CPU-seconds). The thread forks one empty child and lives until the forkserver serves: the
    forkserver's import dies with the *thread* that started it (``forkserver_preload``), so a
    thread that only started it and ended would kill it mid-import."""
    context = _context(start_method)
    if start_method == "forkserver":
        context.set_forkserver_preload(PRELOAD)

    def fork_one() -> None:
        child = context.Process(target=_ready, name="handover-learner-warm-up", daemon=True)
        with interrupts_held():  # the forkserver's too (forkserver_preload)
            child.start()
        child.join()
        child.close()  # its two pipes to the forkserver, now rather than when it is collected

    thread = threading.Thread(target=fork_one, name="learner-warm-up", daemon=True)
    thread.start()
    return thread


class LearnerClient:
    """Caller-side handle of a learner running in a worker process."""

    def __init__(self, config: LearnerConfig, *, snapshot: LearnerSnapshot | None = None,
                 max_restarts: int = 3, start_method: str = START_METHOD) -> None:
        self.config = config
        self.max_restarts = max_restarts
        self.restarts = 0
        self.best: BestPoint | None = None
        #: the batch-opening θ* from the latest reply (an observed point, unlike ``best``)
        self.incumbent: dict[str, float] | None = None
        #: the worker's exact state after its latest reply (what a session stores to resume)
        self.state: LearnerSnapshot | None = snapshot
        #: the posterior utility along each parameter through θ*, from the latest reply
        self.slices: list[PosteriorSlice] = []
        #: the stopping signals of the latest reply (None unless it ended a batch)
        self.settledness: Settledness | None = None
        self.gain: NextBatchGain | None = None
        self._snapshot = snapshot
        self._context = _context(start_method)
        if start_method == "forkserver":  # effective until this process's server has started
            self._context.set_forkserver_preload(PRELOAD)
        self._history: list[ObserveRequest] = []  # answered requests, replayed after a crash
        self._pending: ObserveRequest | None = None
        self._next_id = 0
        self._n_interactions = sum(i.shown for i in snapshot.interactions) if snapshot else 0
        self._ready: Suggestion | None = None
        self._closed = False
        self._start([])

    @classmethod
    def for_session(cls, config: LearnerConfig,
                    snapshot: LearnerSnapshot | None = None) -> LearnerClient:
        """A session's learner: fresh, or exactly as a stored snapshot left it."""
        return cls(config, snapshot=snapshot)

    # -- requests ---------------------------------------------------------------------------
    def submit(self, interactions: list[Interaction] | None = None,
               comparisons: list[Comparison] | None = None) -> int:
        """Send new interactions/comparisons (none: just ask for the next θ); returns at once.

        A request still pending is superseded: its observations are kept, its reply dropped.
        """
        request = ObserveRequest(request_id=self._next_id, interactions=interactions or [],
                                 comparisons=comparisons or [])
        self._next_id += 1
        if self._pending is not None:
            self._history.append(self._pending)
        self._pending = request
        self._n_interactions += sum(i.shown for i in request.interactions)
        self._send(request)
        return request.request_id

    @property
    def pending(self) -> bool:
        """True while the latest request's reply has not been collected (non-blocking)."""
        if self._pending is not None:
            self._collect(block=False)
        return self._pending is not None and self._ready is None

    def poll(self) -> Suggestion | None:
        """The latest request's suggestion if it has arrived, else None; never blocks."""
        self._collect(block=False)
        return self._take()

    def get(self, timeout: float) -> Suggestion:
        """Wait up to ``timeout`` s for the latest request's suggestion, else the fallback."""
        if self._pending is None and self._ready is None:
            raise WorkerError("get() without a submitted request: call submit() first")
        deadline = time.monotonic() + timeout
        while self._ready is None:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return self._fallback()
            self._collect(block=True, timeout=min(remaining, _LIVENESS_PERIOD))
        ready = self._take()
        assert ready is not None, "the loop above ends with a reply"
        return ready

    def close(self, timeout: float = 5.0) -> None:
        """Stop the worker: a polite request first, then terminate if it does not exit; then
        release its pipes and its process handle here, not when the garbage collector gets to
        them (an ended session must leave no file descriptor open behind it). A second call
        does nothing."""
        if self._closed:
            return
        if self._process.is_alive():
            with contextlib.suppress(OSError):  # the worker has just died: nothing to tell it
                self._requests.send(None)
            self._process.join(timeout)
        self._let_go(timeout)
        self._closed = True

    def __enter__(self) -> LearnerClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def pid(self) -> int | None:
        """The worker's process id; None once the client is closed."""
        return None if self._closed else self._process.pid

    # -- internals --------------------------------------------------------------------------
    def _start(self, replay: list[ObserveRequest]) -> None:
        """A worker and its two one-way pipes; this process keeps only its own ends (requests
        out, replies in), so either side sees the other's death as a closed pipe."""
        requests, self._requests = self._context.Pipe(duplex=False)
        self._replies, replies = self._context.Pipe(duplex=False)
        self._process = self._context.Process(
            target=_serve, name="handover-learner", daemon=True,
            args=(self.config.model_dump_json(),
                  None if self._snapshot is None else self._snapshot.model_dump_json(),
                  [r.model_dump(mode="json") for r in replay], requests, replies))
        try:
            with interrupts_held():  # until _serve (or the forkserver's preload) ignores them
                self._process.start()  # hands the worker its ends before it returns
        finally:
            requests.close()
            replies.close()

    def _send(self, request: ObserveRequest) -> None:
        """Send ``request`` to the worker; a dead worker's closed pipe is left to :meth:`_collect`,
        which restarts it and sends the pending request again."""
        with contextlib.suppress(OSError):
            self._requests.send(request.model_dump(mode="json"))

    def _let_go(self, timeout: float) -> None:
        """Release the worker's pipes and process handle (its sentinel); terminated if it still
        runs."""
        if self._process.is_alive():
            logger.warning("learner worker %d did not stop; terminating", self._process.pid)
            self._process.terminate()
            self._process.join(timeout)
        if self._process.is_alive():
            self._process.kill()
            self._process.join()
        self._requests.close()
        self._replies.close()
        self._process.close()

    def _collect(self, *, block: bool, timeout: float = 0.0) -> None:
        """Read replies; keep the one answering the pending request; restart a dead worker."""
        try:
            arrived = self._replies.poll(timeout if block else 0.0)
            message = self._replies.recv() if arrived else None
        except (EOFError, OSError):  # the worker's end closed: it died
            arrived, message = False, None
            self._process.join(_LIVENESS_PERIOD)  # its exit code, for the restart's message
        if not arrived:
            if not self._process.is_alive():
                self._restart()
            return
        reply = WorkerReply.model_validate(message)
        if reply.best is not None:
            self.best = reply.best
        if reply.incumbent is not None:
            self.incumbent = reply.incumbent
        if reply.state is not None:
            self.state = reply.state
            self.slices = reply.slices
            self.settledness = reply.settledness
            self.gain = reply.gain
        if self._pending is None or reply.request_id != self._pending.request_id:
            logger.debug("dropped late reply to request %d", reply.request_id)
            return
        answered, self._pending = self._pending, None
        if reply.error is not None:
            # the worker rejected the request before changing its state: forget the request
            self._n_interactions -= sum(i.shown for i in answered.interactions)
            raise LearningError(reply.error)
        self._history.append(answered)
        assert reply.suggestion is not None
        self._ready = reply.suggestion.model_copy(update={"worker_restarts": self.restarts})

    def _take(self) -> Suggestion | None:
        ready, self._ready = self._ready, None
        return ready

    def _restart(self) -> None:
        if self.restarts >= self.max_restarts:
            raise WorkerError(f"learner worker died (exit code {self._process.exitcode}) and "
                              f"max_restarts = {self.max_restarts} restarts are used up")
        self.restarts += 1
        logger.warning("learner worker died (exit code %s); restart %d of %d, replaying %d "
                       "requests", self._process.exitcode, self.restarts, self.max_restarts,
                       len(self._history))
        self._let_go(_LIVENESS_PERIOD)
        self._start(self._history)
        if self._pending is not None:
            self._send(self._pending)

    @functools.cached_property
    def _fallback_engine(self) -> Any:  # scipy.stats.qmc.Sobol
        """The seeded Sobol sequence of fallback θ, made when a reply is first late: importing
        scipy.stats costs every start of a session ~1 s of CPU, and most sessions need none."""
        from scipy.stats import qmc

        return qmc.Sobol(self.config.box.dim, scramble=True,
                         seed=derive_seed(self.config.seed, 3) % 2**32)

    def _fallback(self) -> Suggestion:
        """A θ the caller can use now: the last batch-opening θ* on a θ* slot, else the next
        fallback Sobol point."""
        slot = self.config.schedule.slot(self._n_interactions)
        if slot.kind is SlotKind.BEST and self.incumbent is not None:
            theta = self.incumbent
        else:
            theta = self.config.box.from_unit(self._fallback_engine.random(1)[0].tolist())
        logger.warning("learner reply late: fallback θ for interaction %d (%s)", slot.index,
                       slot.kind.value)
        if self._pending is not None:
            self._history.append(self._pending)  # its observations stand; its reply is dropped
            self._pending = None
        return Suggestion(theta=theta, slot=slot, fallback=True, worker_restarts=self.restarts)
