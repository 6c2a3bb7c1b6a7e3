"""Reads a magnav MCAP recording with PyPI's `mcap` reader (CRCs checked) and
decodes every message with pycdr2, independently of magnav's code.

The pycdr2 types below mirror idl/magnav.idl; before any message is decoded
each one is checked against the struct of the same name in the IDL stored in
the file's schema (same field names, in the same order), so the decoding is
driven by the schema the file carries.

Usage: read_with_pypi.py FILE.mcap PASS.csv
Checks: every schema 'omgidl' named after its DDS type, every channel 'cdr';
every gradiometer sample of PASS.csv present once (seq 0..N-1, B equal to the
pass's B_x/B_y/B_z); one dipole fix per sample (sample_seq 0..N-1);
publish_time = the sample's source time stamp is set. Prints a summary line.
"""
import re
import sys
from dataclasses import dataclass, fields

from mcap.reader import make_reader
from pycdr2 import IdlEnum, IdlStruct
from pycdr2.types import array, bounded_str, float64, uint32, uint64


class FixMethod(IdlEnum, typename="magnav::msg::FixMethod"):
    METHOD_TED = 0
    METHOD_TED_EGT = 1
    METHOD_EGT = 2
    METHOD_MC = 3
    METHOD_TRACKER = 4
    METHOD_OTHER = 5
    METHOD_PF = 6
    METHOD_AFPF = 7


class MapFixStatus(IdlEnum, typename="magnav::msg::MapFixStatus"):
    MAP_FIX_STATUS_UNKNOWN = 0
    MAP_FIX_STATUS_OK = 1
    MAP_FIX_STATUS_LOST = 2
    MAP_FIX_STATUS_OFF_MAP = 3
    MAP_FIX_STATUS_PARTLY_OBSERVABLE = 4
    MAP_FIX_STATUS_CONVERGING = 5


class NavSource(IdlEnum, typename="magnav::msg::NavSource"):
    NAV_GNSS = 0
    NAV_INS = 1
    NAV_OTHER = 2


@dataclass
class GradiometerSample(IdlStruct, typename="magnav::msg::GradiometerSample"):
    sensor_id: uint32
    stamp_ns: uint64
    seq: uint64
    sensor_position: array[float64, 3]
    B: array[float64, 3]
    T: array[float64, 9]
    sigma_B: float64
    sigma_T: float64


@dataclass
class MagnetometerSample(IdlStruct, typename="magnav::msg::MagnetometerSample"):
    sensor_id: uint32
    stamp_ns: uint64
    seq: uint64
    sensor_position: array[float64, 3]
    B: array[float64, 3]
    sigma_B: float64


@dataclass
class VesselNav(IdlStruct, typename="magnav::msg::VesselNav"):
    vessel_id: uint32
    stamp_ns: uint64
    source: NavSource
    position: array[float64, 3]
    velocity: array[float64, 3]
    heading: float64
    sigma_position: array[float64, 3]
    sigma_velocity: float64
    sigma_heading: float64
    geodetic: array[float64, 3]


@dataclass
class DipoleFix(IdlStruct, typename="magnav::msg::DipoleFix"):
    sensor_id: uint32
    stamp_ns: uint64
    sample_seq: uint64
    method: FixMethod
    valid: bool
    reason: bounded_str[64]
    position: array[float64, 3]
    has_moment: bool
    moment: array[float64, 3]
    condition_number: float64
    covariance: array[float64, 9]


class TrackState(IdlEnum, typename="magnav::msg::TrackState"):
    TRACK_STATE_UNKNOWN = 0
    TRACK_STATE_CONFIRMED = 1
    TRACK_STATE_COASTING = 2


@dataclass
class TrackEstimate(IdlStruct, typename="magnav::msg::TrackEstimate"):
    track_id: uint32
    stamp_ns: uint64
    position: array[float64, 3]
    velocity: array[float64, 3]
    heading: float64
    turn_rate: float64
    covariance: array[float64, 9]
    moment_body: array[float64, 3]
    moment_covariance: array[float64, 9]
    num_sensors: uint32
    usable: bool
    state: TrackState


@dataclass
class SensorPositionEstimate(IdlStruct, typename="magnav::msg::SensorPositionEstimate"):
    sensor_id: uint32
    stamp_ns: uint64
    position: array[float64, 3]
    covariance: array[float64, 9]
    crlb: array[float64, 9]


@dataclass
class MapFix(IdlStruct, typename="magnav::msg::MapFix"):
    vehicle_id: uint32
    stamp_ns: uint64
    method: FixMethod
    method_name: bounded_str[32]
    lat_deg: float64
    lon_deg: float64
    score: float64
    covariance: array[float64, 4]
    status: MapFixStatus


TYPES = {c.__name__: c for c in (GradiometerSample, MagnetometerSample, VesselNav, DipoleFix, TrackEstimate,
                                 SensorPositionEstimate, MapFix)}


def idl_struct_fields(idl, name):
    """Field names of `struct NAME { ... };` in the IDL text, in order."""
    m = re.search(r"struct\s+" + name + r"\s*\{(.*?)\};", idl, re.S)
    if not m:
        return None
    body = re.sub(r"//[^\n]*", "", m.group(1))
    out = []
    for decl in body.split(";"):
        decl = re.sub(r"@\w+", "", decl).strip()
        if decl:
            out.append(re.match(r".*?(\w+)\s*(\[\s*\d+\s*\])?$", decl, re.S).group(1))
    return out


def fail(msg):
    print("FAIL: " + msg)
    sys.exit(1)


def main():
    path, pass_csv = sys.argv[1], sys.argv[2]
    with open(pass_csv) as f:
        lines = [l.strip() for l in f if l.strip() and not l.startswith("#")]
    head = lines[0].split(",")
    rows = [dict(zip(head, l.split(","))) for l in lines[1:]]
    n = len(rows)

    decoded = {}
    publish_times = 0
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        if summary is None or summary.statistics is None:
            fail("no summary/statistics")
        checked_types = set()
        for schema in summary.schemas.values():
            if schema.encoding != "omgidl":
                fail(f"schema {schema.name}: encoding {schema.encoding!r}, not omgidl")
            short = schema.name.split("::")[-1]
            if short not in TYPES:
                fail(f"schema {schema.name}: not a magnav type")
            want = idl_struct_fields(schema.data.decode(), short)
            have = [fl.name for fl in fields(TYPES[short])]
            if want != have:
                fail(f"schema {schema.name}: the file's IDL has fields {want}, the decoder {have}")
            checked_types.add(short)
        for channel in summary.channels.values():
            if channel.message_encoding != "cdr":
                fail(f"channel {channel.topic}: encoding {channel.message_encoding!r}, not cdr")
            if "reliability" not in channel.metadata or "durability" not in channel.metadata:
                fail(f"channel {channel.topic}: no QoS in its metadata {channel.metadata}")
        count = 0
        for schema, channel, message in reader.iter_messages():
            cls = TYPES[schema.name.split("::")[-1]]
            msg = cls.deserialize(message.data)
            decoded.setdefault(channel.topic, []).append(msg)
            if message.publish_time != message.log_time:
                publish_times += 1
            count += 1
        if count != summary.statistics.message_count:
            fail(f"{count} messages read, the statistics say {summary.statistics.message_count}")
        meta = list(reader.iter_metadata())
        if not meta or "domain_id" not in meta[0].metadata or "command_line" not in meta[0].metadata:
            fail("no recording metadata (domain_id, command_line)")

    grad = decoded.get("magnav/gradiometer", [])
    seqs = sorted(m.seq for m in grad)
    if seqs != list(range(n)):
        fail(f"{len(grad)} gradiometer samples, seqs not exactly 0..{n - 1}")
    by_seq = {m.seq: m for m in grad}
    for i, r in enumerate(rows):
        b = by_seq[i].B
        if [float(r["B_x"]), float(r["B_y"]), float(r["B_z"])] != list(b):
            fail(f"gradiometer sample {i}: B {list(b)} differs from the pass's row")
    fixes = decoded.get("magnav/dipole_fix", [])
    fseq = sorted(m.sample_seq for m in fixes)
    if fseq != list(range(n)):
        fail(f"{len(fixes)} dipole fixes, sample_seqs not exactly 0..{n - 1}")
    valid = sum(1 for m in fixes if m.valid)
    print(f"PyPI mcap read {count} messages on {len(decoded)} topic(s) (CRCs checked); pycdr2 decoded all: "
          f"{len(grad)} gradiometer samples equal to the pass, {len(fixes)} dipole fixes ({valid} valid); "
          f"schemas {sorted(checked_types)} match the file's IDL; {publish_times} with a source time stamp")


if __name__ == "__main__":
    main()
