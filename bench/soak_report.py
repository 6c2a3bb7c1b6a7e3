#!/usr/bin/env python3
"""First vs last hour of data of each service in a soak (bench/soak.sh writes its inputs).

  bench/soak_report.py OUT HOURS SPEED_FIELD SPEED_LOCALIZER SPEED_MATCHER [SERVICES]

(SERVICES: those of inverter, tracker, localizer, matcher that ran, space-separated; default all four.)

Reads OUT/<service>.csv (wall_s, cpu_s, rss_kb every few seconds of wall time), OUT/<chain>_replay.times
(the replay's start and end, wall) and the services' logs. The data time of a sample is
(wall - replay end) x speed + SPAN, SPAN = the input's last time - its first (HOURS x 3600 s, or a
little less for the field, which ends with its last vessel): the replay sends each sample on an
absolute schedule (first sample + data time / speed, sleep_until), after its start-up and its wait
for the readers, so the data time is anchored at its end; its wall time beyond SPAN / speed
(start-up: reading the file, the wait for the readers; a lag at the end) is printed beside the
speed. The first hour is [0, 3600] s of data, the last [SPAN - 3600, SPAN]. Per service: CPU s per s of data over
the first and the last hour of data (the CPU time interpolated at the hour's ends), the mean VmRSS
over each of those hours, their ratios, and the samples sent against those the service received.
Writes OUT/<service>_series.csv (data hour, CPU s per
s of data and mean RSS in MB over 10-minute windows of data) for the plot. Exit 1, naming the service,
when a ratio exceeds LIMIT = 1.5, a service received fewer samples than were sent, or the matcher's
filter said lost at more than LOST_STEPS_LIMIT (1 %) of its steps.
"""
import bisect
import csv
import os
import re
import sys

LIMIT = 1.5
LOST_STEPS_LIMIT = 0.01  # a matcher whose filter says lost at more than 1 % of its steps fails the soak
SERVICES = [  # service, chain
    ('inverter', 'field'), ('tracker', 'field'), ('localizer', 'localizer'), ('matcher', 'matcher')]


def rows(path):
    return sum(1 for line in open(path) if line.strip() and not line.startswith('#')) - 1


def last_match(path, pattern):
    found = None
    for line in open(path, errors='replace'):
        m = re.search(pattern, line)
        if m:
            found = m
    return found


def first_last_t(path):
    """The first and the last value of the first column of a CSV (comment lines skipped)."""
    with open(path, 'rb') as f:
        first = None
        for line in f:
            if line.startswith(b'#') or not line.strip():
                continue
            try:
                first = float(line.split(b',')[0])
                break
            except ValueError:  # the header
                continue
        f.seek(max(0, os.path.getsize(path) - 4096))
        last = float([l for l in f.read().splitlines() if l.strip()][-1].split(b',')[0])
    return first, last


def data_span(out, hours, chain):
    """Seconds of data the chain's replay sends, first sample to last."""
    h = '%g' % hours
    if chain == 'field':
        a, b = first_last_t(os.path.join(out, 'field_%sh.csv' % h))
    elif chain == 'localizer':
        a, b = first_last_t(os.path.join(out, 'racetrack_meas_%sh.csv' % h))
        c, d = first_last_t(os.path.join(out, 'racetrack_gnss_%sh.csv' % h))
        a, b = min(a, c), max(b, d)
    else:
        a, b = first_last_t(os.path.join(out, 'mappath_%sh.csv' % h))  # k, one step per second (--step-period 1)
    return b - a


def counts(out, hours, service):
    """(sent, received, output description) from the data files and the service's log."""
    h = '%g' % hours
    log = os.path.join(out, service + '.log')
    if service in ('inverter', 'tracker'):
        sent = rows(os.path.join(out, 'field_%sh.csv' % h))
        m = last_match(log, r'stopping after (\d+) samples \((\d+) repeated, (\d+) missing')
        received = int(m.group(1)) if m else 0
        if service == 'inverter':
            f = last_match(log, r'(\d+) fixes, (\d+) lost')
            what = '%s fixes' % (f.group(1) if f else '?')
        else:
            f = last_match(log, r'(\d+) estimates \((\d+) not published\), (\d+) tracks')
            late = last_match(log, r'(\d+) late,')
            what = '%s tracks, %s estimates, %s late' % (f.group(3), f.group(1), late.group(1) if late else '?') \
                if f else '?'
    elif service == 'localizer':
        sent = rows(os.path.join(out, 'racetrack_meas_%sh.csv' % h)) + rows(os.path.join(out, 'racetrack_gnss_%sh.csv' % h))
        m = last_match(log, r'(\d+) magnetometer \+ (\d+) vessel_nav samples in')
        received = int(m.group(1)) + int(m.group(2)) if m else 0
        s = last_match(log, r'stopping after (\d+) samples used, (\d+) skipped, \d+ repeated, \d+ missing, (\d+) estimates')
        what = '%s estimates, %s used, %s skipped' % (s.group(3), s.group(1), s.group(2)) if s else '?'

    else:
        sent = 2 * rows(os.path.join(out, 'mappath_%sh.csv' % h))
        m = last_match(log, r'stopping after (\d+) vessel_nav \+ (\d+) magnetometer in, (\d+) steps \((\d+) updates.*'
                            r', (\d+) lost steps[;)].* (\d+) fixes out')
        received = int(m.group(1)) + int(m.group(2)) if m else 0
        what = '%s steps, %s lost steps, %s fixes' % (m.group(3), m.group(5), m.group(6)) if m else '?'
    return sent, received, what


def main():
    if len(sys.argv) not in (6, 7):
        sys.exit(__doc__)
    out, hours = sys.argv[1], float(sys.argv[2])
    speeds = {'field': sys.argv[3], 'localizer': sys.argv[4], 'matcher': sys.argv[5]}
    failed = []
    table = ['| service | data (h) | speed (replay wall s beyond data / speed) | CPU s per s of data, first h | last h | ratio | '
             'RSS first h (MB) | last h (MB) | ratio | sent / received (lost) | output |',
             '|---|---|---|---|---|---|---|---|---|---|---|']
    chosen = sys.argv[6].split() if len(sys.argv) == 7 else [s for s, _ in SERVICES]
    for service, chain in SERVICES:
        if service not in chosen:
            continue
        start, end = (float(x) for x in open(os.path.join(out, chain + '_replay.times')).read().split())
        speed = float(speeds[chain])
        span = data_span(out, hours, chain)
        extra = (end - start) - span / speed
        data = [r for r in csv.DictReader(open(os.path.join(out, service + '.csv'))) if r['rss_kb']]
        t = [(float(r['wall_s']) - end) * speed + span for r in data]
        cpu = [float(r['cpu_s']) for r in data]
        rss = [int(r['rss_kb']) / 1024.0 for r in data]

        def cpu_at(x):
            i = bisect.bisect_left(t, x)
            if i <= 0:
                return cpu[0]
            if i >= len(t):
                return cpu[-1]
            return cpu[i - 1] + (cpu[i] - cpu[i - 1]) * (x - t[i - 1]) / (t[i] - t[i - 1])

        def rss_mean(a, b):
            v = [m for x, m in zip(t, rss) if a <= x <= b]
            return sum(v) / len(v) if v else float('nan')

        c1 = (cpu_at(3600.0) - cpu_at(0.0)) / 3600.0
        c2 = (cpu_at(span) - cpu_at(span - 3600.0)) / 3600.0
        m1, m2 = rss_mean(0.0, 3600.0), rss_mean(span - 3600.0, span)
        rc, rm = c2 / c1 if c1 > 0 else float('inf'), m2 / m1
        sent, received, what = counts(out, hours, service)
        lost = sent - received
        table.append('| %s | %.2f | %gx (%.1f s) | %.5f | %.5f | **%.2f** | %.1f | %.1f | **%.2f** | %d / %d (%d) | %s |' % (
            service, span / 3600, speed, extra, c1, c2, rc, m1, m2, rm, sent, received, lost, what))
        with open(os.path.join(out, service + '_series.csv'), 'w') as f:
            f.write('data_h,cpu_s_per_data_s,rss_mb\n')
            w = 600.0
            a = 0.0
            while a + w <= span + 1e-6:
                f.write('%.4f,%.6f,%.2f\n' % ((a + w / 2) / 3600, (cpu_at(a + w) - cpu_at(a)) / w, rss_mean(a, a + w)))
                a += w
        if rc > LIMIT:
            failed.append('%s: CPU per s of data in the last hour is %.2fx the first (limit %.1fx)' % (service, rc, LIMIT))
        if rm > LIMIT:
            failed.append('%s: RSS in the last hour is %.2fx the first (limit %.1fx)' % (service, rm, LIMIT))
        if lost > 0:
            failed.append('%s: received %d of the %d samples sent (%d lost; replay slower?)' % (service, received, sent,
                                                                                             lost))
        steps = re.match(r'(\d+) steps, (\d+) lost steps', what) if service == 'matcher' else None
        if steps and int(steps.group(2)) > LOST_STEPS_LIMIT * int(steps.group(1)):
            failed.append('matcher: its filter said lost at %s of %s steps (limit %g %%): the estimates are not '
                          'trustworthy; check them against the path\'s truth (docs/ACCURACY.md, "Dense readings")'
                          % (steps.group(2), steps.group(1), 100 * LOST_STEPS_LIMIT))
    print('\n'.join(table))
    if failed:
        print('SOAK FAILED:\n  ' + '\n  '.join(failed))
        sys.exit(1)
    print('soak passed: every service\'s last hour within %.1fx of its first in CPU per s of data and in RSS, '
          'nothing lost, the matcher lost at most %g %% of its steps' % (LIMIT, 100 * LOST_STEPS_LIMIT))


if __name__ == '__main__':
    main()
