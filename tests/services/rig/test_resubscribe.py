"""The pauses of a subscriber before it subscribes again after an ended run (issue 33)."""

import grpc
import pytest

from services.rig.resubscribe import RUN_ENDED_FIRST_PAUSE_S, RUN_ENDED_MAX_PAUSE_S, RunEndedBackoff, run_ended


def test_the_pause_doubles_up_to_the_cap_and_a_frame_resets_it():
    backoff = RunEndedBackoff(first_s=0.5, max_s=2.0)
    assert [backoff.pause() for _ in range(5)] == [0.5, 1.0, 2.0, 2.0, 2.0]
    backoff.reset()
    assert backoff.pause() == 0.5


def test_the_default_caps_at_the_reconnection_backoff():
    from services.rig.grpc_util import MAX_RECONNECT_BACKOFF_MS

    backoff = RunEndedBackoff()
    pauses = [backoff.pause() for _ in range(4)]
    assert pauses[0] == RUN_ENDED_FIRST_PAUSE_S and max(pauses) == RUN_ENDED_MAX_PAUSE_S
    assert RUN_ENDED_MAX_PAUSE_S == MAX_RECONNECT_BACKOFF_MS / 1000


@pytest.mark.parametrize(("first", "most"), [(0.0, 1.0), (2.0, 1.0), (-1.0, 1.0)])
def test_a_bad_pause_is_refused_naming_it(first, most):
    with pytest.raises(ValueError, match=f"first_s: {first}"):
        RunEndedBackoff(first_s=first, max_s=most)


class _Refused(grpc.RpcError):
    def __init__(self, code):
        self._code = code

    def code(self):
        return self._code


def test_only_failed_precondition_says_the_run_has_ended():
    assert run_ended(_Refused(grpc.StatusCode.FAILED_PRECONDITION))
    for code in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.CANCELLED, grpc.StatusCode.INVALID_ARGUMENT,
                 grpc.StatusCode.ALREADY_EXISTS):
        assert not run_ended(_Refused(code))
