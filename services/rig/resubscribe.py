"""When a subscriber of the host's frame stream (a worker, the compositor) subscribes again after
a run has ended.

A host whose run has ended keeps answering for a short linger before it exits (late
acknowledgements, status requests) and refuses every new subscription meanwhile with
FAILED_PRECONDITION. A subscriber that came straight back after the end of its stream, and after
each refusal, asked thousands of times in that linger (3,916 subscriptions in 2 s in a soak,
issue 33). So it pauses: RUN_ENDED_FIRST_PAUSE_S after a run, doubling with each refusal up to
RUN_ENDED_MAX_PAUSE_S, and from the first pause again once a stream has brought a frame.
Once the host has exited the subscription waits for the next host (wait_for_ready), so the pause
only bounds the asking while an ended host lingers.
"""

from __future__ import annotations

import grpc

#: First pause after a run ended, seconds.
RUN_ENDED_FIRST_PAUSE_S = 0.5

#: Longest pause, seconds: the same cap as the channels' reconnection backoff
#: (grpc_util.MAX_RECONNECT_BACKOFF_MS), so that a subscriber follows the next host within a
#: second of its start, as after any restart.
RUN_ENDED_MAX_PAUSE_S = 1.0


def run_ended(exc: grpc.RpcError) -> bool:
    """Whether SubscribeFrames failed because the host's run has ended (host.proto: the host
    refuses new subscriptions with FAILED_PRECONDITION once its run is over)."""
    return exc.code() == grpc.StatusCode.FAILED_PRECONDITION


class RunEndedBackoff:
    """The pauses of one subscriber before it subscribes again after an ended run (module doc).

    Args:
        first_s: the first pause, seconds.
        max_s: the longest, seconds.
    """

    def __init__(self, *, first_s: float = RUN_ENDED_FIRST_PAUSE_S, max_s: float = RUN_ENDED_MAX_PAUSE_S) -> None:
        if not 0 < first_s <= max_s:
            raise ValueError(f"first_s: {first_s} must be > 0 and <= max_s ({max_s})")
        self.first_s = first_s
        self.max_s = max_s
        self._next = first_s

    def pause(self) -> float:
        """The pause before the next subscription, seconds; each call doubles the next one (up to
        max_s)."""
        pause, self._next = self._next, min(self.max_s, self._next * 2.0)
        return pause

    def reset(self) -> None:
        """A stream brought a frame: the next run's end pauses first_s again."""
        self._next = self.first_s
