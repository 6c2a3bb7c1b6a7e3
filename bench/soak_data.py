#!/usr/bin/env python3
"""Long simulated inputs for the service soak (bench/soak.sh; docs/BENCHMARKS.md "Soak of the four
services"). Standard library + `magnav simulate`; the same files on every run (fixed seeds, chosen
before any soak was run).

  bench/soak_data.py MAGNAV_BIN OUT_DIR HOURS [CHAINS="field localizer matcher"]

writes into OUT_DIR (each skipped when it exists):
  field_<H>h.csv       the inverter's and tracker's input: the 3x3 field of docs' reference §5
                       (tensor gradiometers 40 m apart, z = 0, 10 Hz, fluxgate noise, B0 below)
                       for HOURS (it ends with the last vessel: 5.94 h for 6), one AUV-sized
                       vessel crossing it every 360 s (start 150 m out
                       on a random bearing, through the field within 30 m of its centre, 1.5-2.5
                       m/s, 5-8 m above, moment ~2e3 A*m^2 in a random body direction); seed 2201
  racetrack_meas_<H>h.csv, racetrack_gnss_<H>h.csv, racetrack_deployment.csv
                       the localizer's input, as bench/localizer_age.sh: the racetrack survey of
                       tests/localizer/racetrack.h (6 sensors at 25 m, 2 Hz, sigma_B 1 nT; GNSS
                       sigma 2 m at 1 Hz; deployment prior sigma 10 m) for HOURS; seeds 100, 101
  mappath_<H>h.csv     the matcher's input: a path over tests/data/reference/map_crustal_anomaly.csv
                       for HOURS at 1 step per second of 2 m (a 2 m/s vehicle), heading a random
                       walk of 0.014 rad per step steered back towards the centre within 2 km of
                       the edge (kept 1.5 km inside); ins = true + a 0.01 deg offset + a random
                       walk of U(+-0.5) x 0.001 x sqrt(2/100) deg per step and axis (the reference
                       paths' drift per 100 m, scaled to 2 m steps); meas_nT = the map's bicubic
                       value at the true point + N(0, 3 nT) (scripts/heldout_mappaths); seed 2203
"""
import csv
import importlib.machinery
import importlib.util
import math
import os
import random
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, '..')
B0 = '2e-05,1e-06,4.5e-05'
FIELD_PERIOD_S = 360.0


def field(magnav, out, hours):
    name = os.path.join(out, 'field_%gh.csv' % hours)
    if os.path.exists(name):
        return
    rng = random.Random(2201)
    vessels = []
    n = int(hours * 3600 / FIELD_PERIOD_S)
    for i in range(n):
        bearing = rng.uniform(0, 2 * math.pi)           # where it comes from, seen from the centre
        lateral = rng.uniform(-30, 30)                  # miss distance of the centre
        speed = rng.uniform(1.5, 2.5)
        z = -rng.uniform(5, 8)
        heading = bearing + math.pi                     # towards the centre
        sx = 150 * math.cos(bearing) - lateral * math.sin(bearing)
        sy = 150 * math.sin(bearing) + lateral * math.cos(bearing)
        m = [rng.gauss(0, 1) for _ in range(3)]
        norm = math.sqrt(sum(v * v for v in m))
        moment = [2000 * v / norm for v in m]
        duration = min(300.0 / speed, FIELD_PERIOD_S - 20)
        t0 = 10 + i * FIELD_PERIOD_S
        vessels.append('id=%d;t0=%g;start=%.3f,%.3f,%.3f;speed=%.3f;heading=%.6f;moment=%.1f,%.1f,%.1f;turns=%.3f:0' % (
            i + 1, t0, sx, sy, z, speed, heading, moment[0], moment[1], moment[2], duration))
    # The field lasts while a vessel exists: a last, far and weak one keeps it going to HOURS.
    last_t0 = 10 + n * FIELD_PERIOD_S
    if hours * 3600 > last_t0:
        vessels.append('id=%d;t0=%g;start=5000,5000,-5;speed=1;heading=0;moment=1,0,0;turns=%.3f:0' % (
            n + 1, last_t0, hours * 3600 - last_t0))
    cmd = [magnav, 'simulate', '--output', name + '.tmp', '--truth', os.path.join(out, 'field_truth_%gh.csv' % hours),
           '--noise', 'fluxgate', '--b0', B0, '--grid', '3,3,40', '--rate', '10', '--seed', '2201']
    for v in vessels:
        cmd += ['--vessel', v]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    os.replace(name + '.tmp', name)


def racetrack(magnav, out, hours):
    meas = os.path.join(out, 'racetrack_meas_%gh.csv' % hours)
    gnss = os.path.join(out, 'racetrack_gnss_%gh.csv' % hours)
    if os.path.exists(meas) and os.path.exists(gnss):
        return
    loop = 400 + 40 * math.pi
    n = math.ceil(hours * 3600 / loop)
    turns = ','.join(['200:0', '%.12f:0.05' % (20 * math.pi)] * (2 * n))
    sensors = [(-80, -40), (0, -70), (70, -30), (-40, 15), (40, 20), (100, 30)]
    pas, truth = os.path.join(out, 'racetrack_pass.csv'), os.path.join(out, 'racetrack_truth.csv')
    subprocess.run([magnav, 'simulate', '--output', pas, '--truth', truth, '--sigma-b', '1e-9',
                    '--moment-body', '-15000,5000,20000', '--start', '-250,-60,0', '--speed', '2.5', '--heading', '0',
                    '--turns', turns, '--sensors', ';'.join('%d,%d,25' % s for s in sensors), '--rate', '2',
                    '--b0', '0,0,0', '--seed', '100'], check=True, stdout=subprocess.DEVNULL)
    end = hours * 3600
    rng = random.Random(101)
    with open(pas) as f, open(meas, 'w') as m:
        m.write('# moment_body_Am2: -15000, 5000, 20000\n# vessel_z_m: 0\n# sigma_B_T: 1e-9\nt,sensor_id,B_x,B_y,B_z\n')
        for row in csv.DictReader(l for l in f if not l.startswith('#')):
            if float(row['t']) <= end:
                m.write('%s,%s,%s,%s,%s\n' % (row['t'], row['sensor_id'], row['B_x'], row['B_y'], row['B_z']))
    with open(truth) as f, open(gnss, 'w') as g:
        g.write('t,x,y,sigma\n')
        for row in csv.DictReader(l for l in f if not l.startswith('#')):
            t = float(row['t'])
            if t <= end and abs(t - round(t)) < 1e-9:
                g.write('%s,%r,%r,2\n' % (row['t'], float(row['x']) + rng.gauss(0, 2), float(row['y']) + rng.gauss(0, 2)))
    with open(os.path.join(out, 'racetrack_deployment.csv'), 'w') as d:
        d.write('sensor_id,x,y,z,sigma_xy\n')
        for j, (x, y) in enumerate(sensors):
            d.write('%d,%r,%r,25,10\n' % (j, x + rng.gauss(0, 10), y + rng.gauss(0, 10)))
    os.remove(pas)


def mappath(out, hours):
    name = os.path.join(out, 'mappath_%gh.csv' % hours)
    if os.path.exists(name):
        return
    loader = importlib.machinery.SourceFileLoader('heldout_mappaths', os.path.join(ROOT, 'scripts', 'heldout_mappaths'))
    spec = importlib.util.spec_from_loader('heldout_mappaths', loader)
    hm = importlib.util.module_from_spec(spec)
    loader.exec_module(hm)
    m = hm.read_map(os.path.join(ROOT, 'tests', 'data', 'reference', 'map_crustal_anomaly.csv'))
    lat0, lon0, step, nla, nlo, _ = m
    kn, ke = hm.K_NORTH, hm.K_EAST
    rng = random.Random(2203)
    lo_lat, hi_lat = lat0 + 1500 / kn, lat0 + (nla - 1) * step - 1500 / kn
    lo_lon, hi_lon = lon0 + 1500 / ke, lon0 + (nlo - 1) * step - 1500 / ke
    c_lat, c_lon = (lo_lat + hi_lat) / 2, (lo_lon + hi_lon) / 2
    steps, ds = int(hours * 3600), 2.0
    lat, lon, h = c_lat, c_lon, rng.uniform(0, 2 * math.pi)
    d = rng.uniform(0, 2 * math.pi)
    off = (0.01 * math.cos(d), 0.01 * math.sin(d))
    e = [0.0, 0.0]
    drift = 0.001 * math.sqrt(ds / 100.0)
    with open(name + '.tmp', 'w') as f:
        f.write('# soak map path (bench/soak_data.py): %d steps of %g m, 1 per second, offset 0.01 deg, '
                'drift U(+-0.5) x %g deg/step/axis, noise 3 nT, bicubic map value\n' % (steps, ds, drift))
        f.write('k,true_lat,true_lon,ins_lat,ins_lon,meas_nT\n')
        for k in range(steps):
            f.write('%d,%.12f,%.12f,%.12f,%.12f,%.9f\n' % (k, lat, lon, lat + off[0] + e[0], lon + off[1] + e[1],
                                                           hm.bicubic(m, lat, lon) + rng.gauss(0, 3)))
            near = (lat - lo_lat) * kn < 2000 or (hi_lat - lat) * kn < 2000 or \
                (lon - lo_lon) * ke < 2000 or (hi_lon - lon) * ke < 2000
            if near:  # turn towards the centre by at most 0.01 rad per step
                want = math.atan2((c_lon - lon) * ke, (c_lat - lat) * kn)
                dh = math.atan2(math.sin(want - h), math.cos(want - h))
                h += max(-0.01, min(0.01, dh))
            h += rng.gauss(0.0, 0.1 * math.sqrt(ds / 100.0))
            lat += ds * math.cos(h) / kn
            lon += ds * math.sin(h) / ke
            lat, lon = min(max(lat, lo_lat), hi_lat), min(max(lon, lo_lon), hi_lon)
            e[0] += rng.uniform(-0.5, 0.5) * drift
            e[1] += rng.uniform(-0.5, 0.5) * drift
    os.replace(name + '.tmp', name)


def main():
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__)
    magnav, out, hours = sys.argv[1], sys.argv[2], float(sys.argv[3])
    chains = sys.argv[4].split() if len(sys.argv) == 5 else ['field', 'localizer', 'matcher']
    os.makedirs(out, exist_ok=True)
    if 'field' in chains:
        field(magnav, out, hours)
    if 'localizer' in chains:
        racetrack(magnav, out, hours)
    if 'matcher' in chains:
        mappath(out, hours)


if __name__ == '__main__':
    main()
