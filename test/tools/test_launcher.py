"""launcher: real node processes; restart after SIGKILL, clean SIGINT, crash loop, bag + report."""
import os
import re
import signal
import time

from wz_tools_helpers import LineReader, run_cli, start_cli, wait_gone, write_launch_bag

DUMMY = 'wz_launch_fixtures.dummy_node'
_STARTED = re.compile(r'^\[launch\] started (\S+) \(pid (\d+)\)')


def _started(reader, name, timeout=30.0, after=0):
    line = reader.wait_for(lambda s: (m := _STARTED.match(s)) is not None
                           and m.group(1) == name and int(m.group(2)) != after, timeout)
    assert line, f'{name} not started:\n{reader.text()}'
    return int(_STARTED.match(line).group(2))


def _stop(proc):
    if proc.poll() is None:
        proc.kill()
        proc.wait(5)


# The SIGKILL tests run without the launcher's 32 MB shared-memory profile: a SIGKILLed
# participant leaves its segment in /dev/shm (Fast DDS's default one is 0.5 MB).
NO_SHM = ('--dds-profile', 'none')


def test_restart_after_sigkill_and_clean_sigint():
    proc = start_cli('launch', '--nodes', f'{DUMMY},second={DUMMY}', *NO_SHM)
    reader = LineReader(proc)
    try:
        first = _started(reader, 'dummy_node')
        second = _started(reader, 'second')
        assert reader.wait_for(lambda s: s.startswith('[dummy_node] dummy ready'), 30), \
            reader.text()
        os.kill(first, signal.SIGKILL)
        assert reader.wait_for(lambda s: 'dummy_node exited (signal SIGKILL); restart #1'
                               in s, 10), reader.text()
        again = _started(reader, 'dummy_node', after=first)
        assert reader.wait_for(lambda s: s.startswith('[second] dummy ready'), 30)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(10) == 0, reader.text()
        assert time.monotonic() - t0 < 5.5
        assert wait_gone([first, second, again], 2.0), 'orphaned node process'
    finally:
        _stop(proc)


def test_children_die_with_a_killed_launcher():
    proc = start_cli('launch', '--nodes', DUMMY, *NO_SHM)
    reader = LineReader(proc)
    try:
        pid = _started(reader, 'dummy_node')
        assert reader.wait_for(lambda s: 'dummy ready' in s, 30), reader.text()
        proc.send_signal(signal.SIGKILL)
        proc.wait(5)
        assert wait_gone([pid], 3.0), 'node survived its SIGKILLed launcher'
    finally:
        _stop(proc)


def test_crash_loop_exits_3_naming_the_node():
    proc = start_cli('launch', '--nodes', 'wz_launch_fixtures.crash_node', '--max-restarts', '2')
    reader = LineReader(proc)
    try:
        code = proc.wait(30)
    finally:
        _stop(proc)
    reader.wait_for(lambda s: 'exit code' in s, 2)
    out = reader.text()
    assert code == 3, out
    assert 'crash_node exited (code 1) 3 times' in out and 'giving up' in out, out
    assert out.count('[crash_node] crash_node: failing on purpose') == 3


def test_bag_replay_report_and_exit_0(tmp_path):
    bag = write_launch_bag(tmp_path / 'bag', frames=12)
    proc = run_cli('launch', '--nodes', DUMMY, '--bag', str(bag), '--report', '--drain', '0.5',
                   timeout=90)
    out = proc.stdout
    assert proc.returncode == 0, out + proc.stderr
    assert re.search(r'/workzone/detections\s+12\s', out), out
    assert 'ground truth: 12 frames, 8 with signs; with detections 8 (100.0 %)' in out, out


def test_unreadable_bag_exit_2_before_nodes(tmp_path):
    proc = run_cli('launch', '--nodes', DUMMY, '--bag', str(tmp_path / 'missing'), timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.strip().count('\n') == 0 and 'not found' in proc.stderr
    assert 'started' not in proc.stdout and 'Traceback' not in proc.stderr
