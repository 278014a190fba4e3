from app.events.alarm import AlarmLogic
from app.vision.detections import Box, Detection

MOVING = [Detection(Box(0, 0, 10, 10), (5, 5), 100.0, track_id=3)]


def feed(logic, pattern, fps=10.0):
    updates = []
    for i, moving in enumerate(pattern):
        updates.append(logic.update(i, i / fps, MOVING if moving else []))
    return updates


def test_event_starts_on_first_motion_and_ends_after_quiet_period():
    logic = AlarmLogic(quiet_s=0.5)
    updates = feed(logic, [0, 1, 1, 1, 0, 0, 0, 0, 0, 0])
    started = [i for i, u in enumerate(updates) if u.started]
    ended = [(i, u.ended) for i, u in enumerate(updates) if u.ended]
    assert started == [1]
    ((at, event),) = ended
    assert at == 8  # 0.5 s after the last motion at frame 3
    assert (event.start_frame, event.end_frame) == (1, 3)
    assert event.max_area == 100.0 and event.track_ids == {3}


def test_short_pause_does_not_split_an_event_but_a_long_one_does():
    logic = AlarmLogic(quiet_s=0.5)
    updates = feed(logic, [1, 1, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0, 1])
    assert sum(1 for u in updates if u.started) == 2
    assert [u.started.id for u in updates if u.started] == [1, 2]


def test_finish_closes_the_open_event():
    logic = AlarmLogic()
    feed(logic, [1, 1])
    event = logic.finish()
    assert event is not None and event.end_frame == 1
    assert logic.finish() is None


def test_a_new_object_joining_an_open_event_is_announced():
    logic = AlarmLogic()
    first = [Detection(Box(0, 0, 10, 10), (5, 5), 100.0, track_id=1)]
    both = [*first, Detection(Box(50, 0, 10, 10), (55, 5), 100.0, track_id=2)]
    assert logic.update(0, 0.0, first).started is not None
    assert logic.update(1, 0.1, first).newcomers == ()
    update = logic.update(2, 0.2, both)
    assert update.started is None and update.newcomers == (2,)
    assert logic.update(3, 0.3, both).newcomers == ()


def test_objects_joining_within_the_alarm_gap_are_announced_together_by_the_next_alarm():
    logic = AlarmLogic(alarm_gap_s=1.0)
    crowd = [
        Detection(Box(20 * i, 0, 10, 10), (20 * i + 5, 5), 100.0, track_id=i) for i in (1, 2, 3)
    ]
    assert logic.update(0, 0.0, crowd[:1]).started is not None
    assert logic.update(1, 0.4, crowd[:2]).newcomers == ()  # Too soon after the first alarm.
    assert logic.update(2, 0.8, crowd).newcomers == ()
    assert logic.update(3, 1.0, crowd).newcomers == (2, 3)  # One alarm names both.
    assert logic.update(4, 2.5, crowd).newcomers == ()
    event = logic.finish()
    assert event is not None and event.track_ids == {1, 2, 3}
