"""The classifier's confirmation of tracks (``TrackerConfig.needs_confirmation``).

One false detection (a drum, an orange patch) starts a track that the mean-shift tracker can
follow for many frames on its own, and every published frame is classified again.  With a
classifier reporting back (:meth:`MultiTracker.confirm
<workzone_ros.core.track.multi.MultiTracker.confirm>`, the ``tracker`` node's
``signs_topic``), a track running on its own (no detection this frame) is published only
when

* the classifier's latest answer on it is a sign (a non-background class of category
  ``workzone`` or ``general``), or it has at least :data:`MIN_HITS_UNCONFIRMED` detections;
* and its latest answer is not ``background``: a rejected track is not published on its own
  until a new detection is associated with it (which ends the rejection).

A frame where the track takes a detection is published as before: the detection is the
evidence.  An answer ``unknown`` (box too small, mostly outside the image) is no verdict.
The rule needs a classifier: it applies once :meth:`Confirmations.note` has been called, so a
tracker no classifier reports to (``evaluate tracker``, the node with an empty
``signs_topic``) behaves as before; ``needs_confirmation=False`` is the previous rule.
"""
from __future__ import annotations

from typing import Any, Iterable

from workzone_ros.interfaces import Track

__all__ = ['SIGN_CATEGORIES', 'MIN_HITS_UNCONFIRMED', 'Confirmations', 'classifier_verdicts']

#: Categories of a classifier answer that confirm a track as a sign.
SIGN_CATEGORIES = ('workzone', 'general')
#: Detections a track needs to run on its own without the classifier's confirmation.
MIN_HITS_UNCONFIRMED = 2


def classifier_verdicts(track_ids: Iterable[Any], signs: Iterable[Any]
                        ) -> tuple[set[int], set[int]]:
    """``(signs, rejected)`` track ids of one classified frame.

    Args:
        track_ids: the ids of the boxes the classifier was given (a ``Tracks`` payload's;
            0 and None, a detection without a track, are ignored).
        signs: what it published for that frame (``Sign`` items: ``track_id``,
            ``category``).  The classifier does not publish ``background`` answers, so a
            given track that has no sign of any category (not even ``unknown``) was rejected.
    """
    seen = {s.track_id for s in signs if s.track_id is not None}
    confirmed = {int(s.track_id) for s in signs
                 if s.track_id is not None and s.category in SIGN_CATEGORIES}
    rejected = {int(t) for t in track_ids if t and t not in seen}
    return confirmed, rejected


class Confirmations:
    """The classifier's latest verdict per track id and the publication rule (module
    docstring)."""

    def __init__(self) -> None:
        #: a classifier reports (:meth:`note` was called): the rule applies.
        self.active = False
        self._verdict: dict[int, bool] = {}          # track id -> sign (True) / background

    def clear(self) -> None:
        """Forget every verdict (the tracks were dropped); a classifier still reports."""
        self._verdict.clear()

    def note(self, signs: Iterable[int], rejected: Iterable[int], live: Iterable[int]) -> None:
        """Record the verdicts on the ``live`` tracks among ``signs`` and ``rejected``."""
        self.active = True
        live = set(live)
        for tid in rejected:
            if tid in live:
                self._verdict[int(tid)] = False
        for tid in signs:
            if tid in live:
                self._verdict[int(tid)] = True

    def verdict(self, track_id: int) -> Any:
        """True (a sign), False (background) or None (no verdict) for ``track_id``."""
        return self._verdict.get(track_id)

    def gate(self, tracks: list[Track], needed: bool, live: Iterable[int]) -> list[Track]:
        """The ``tracks`` to publish: those running on its own (``source='tracking'``) only
        under the rule when it is ``needed`` and active; a detection-led track ends its
        rejection.  Verdicts of tracks not ``live`` are forgotten."""
        live = set(live)
        for tid in [t for t in self._verdict if t not in live]:
            del self._verdict[tid]
        out = []
        for t in tracks:
            v = self._verdict.get(t.track_id)
            if t.source != 'tracking':
                if v is False:
                    del self._verdict[t.track_id]    # a new detection: judged afresh
            elif needed and self.active and (
                    v is False or (v is not True and t.hits < MIN_HITS_UNCONFIRMED)):
                continue
            out.append(t)
        return out
