"""The launcher's console: configuration blocks folded into one line, state changes described."""
import io

from workzone_ros.interfaces import Evidence, Header, Time, WorkzoneState
from workzone_ros.tools.launch_console import Console, describe_state


def test_configuration_blocks_go_to_the_log_file_not_the_console(tmp_path):
    out, log = io.StringIO(), tmp_path / 'launch.log'
    console = Console(out, log)
    console('tracker', '[INFO] [1.0] [tracker]: configuration of /tracker:')
    for k in range(80):
        console('tracker', f'  param_{k} = {k}')
    console('tracker', 'tracking started')
    console('launch', 'started fusion (pid 1)')
    console.close()
    shown = out.getvalue().splitlines()
    assert len(shown) == 3, shown
    assert 'configuration logged' in shown[0] and str(log) in shown[0]
    assert shown[1:] == ['[tracker] tracking started', '[launch] started fusion (pid 1)']
    text = log.read_text()
    assert '  param_79 = 79' in text and 'tracking started' in text


def test_verbose_shows_everything():
    out = io.StringIO()
    console = Console(out, None, verbose=True)
    console('a', 'configuration of /a:')
    console('a', '  x = 1')
    assert out.getvalue().splitlines() == ['[a] configuration of /a:', '[a]   x = 1']


def test_a_state_line_says_what_a_planner_acts_on():
    state = WorkzoneState(
        header=Header(stamp=Time(sec=3)), active=True, likelihood=0.87, phase='inside',
        speed_limit_mph=45, lane_shift='left', lanes_closed=['right'], stale_inputs=['lidar'],
        evidence=[Evidence(class_key='work_zone_begin', weight=0.9, stamp=Time(sec=2),
                           track_id=7, distance_m=31.0)])
    line = describe_state(state)
    for part in ('INSIDE', 'p=0.87', '45 mph', 'shift left', 'closed right', 'STALE lidar',
                 'work_zone_begin#7@31m'):
        assert part in line, line
    unread = WorkzoneState(header=Header(stamp=Time(sec=3)), active=True, likelihood=0.5,
                           phase='inside', unknowns=['speed_limit_value'])
    assert 'speed unread' in describe_state(unread)
