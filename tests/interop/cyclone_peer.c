/*
 * cyclone_peer: a small Eclipse Cyclone DDS (C API, 0.10) program that talks to
 * magnav's services on the same topics, as any other vendor's application
 * would. It is built against Debian's cyclonedds-dev from the project's own
 * idl/magnav.idl (compiled by Cyclone's idlc), and driven by
 * tests/interop/cyclone_interop_test.sh. Its configuration (loopback only)
 * comes from $CYCLONEDDS_URI (config/cyclonedds_loopback.xml), its domain id
 * from $MAGNAV_DOMAIN_ID; with $MAGNAV_ROS2_NAMES=1 it uses ROS 2's topic and
 * type names, as magnav's programs then do.
 *
 *   cyclone_peer expect-samples FILE TIMEOUT_S [volatile]
 *       Subscribes magnav/gradiometer and waits until it has received every row
 *       of the gradiometer CSV FILE (as `magnav replay --input FILE` sends it:
 *       per-sensor seq from 0 in file order), each exactly once and bit for
 *       bit equal to the file. Prints "ready" once its reader exists and
 *       "received R of N, M differ, D repeated" at the end. Exit 0 iff all N
 *       came, none differ, none repeated. The reader is RELIABLE and
 *       TRANSIENT_LOCAL (docs/INTEROP.md), or VOLATILE with "volatile".
 *   cyclone_peer send-samples FILE [magnav|default|sensor_data]
 *       Publishes every row of FILE on magnav/gradiometer (sigma_B and sigma_T
 *       from the file's "# sigma_B_T:" and "# sigma_T_Tpm:" lines) once a
 *       reader is matched, then waits until it has acknowledged them all. The
 *       writer's QoS: magnav's (RELIABLE, TRANSIENT_LOCAL; the default), or a
 *       stock driver's: Cyclone DDS's default writer QoS (RELIABLE, VOLATILE,
 *       KEEP_LAST 1: dds_create_writer with no QoS) or ROS 2's sensor-data QoS
 *       (BEST_EFFORT, VOLATILE, KEEP_LAST 5). The stock ones are paced at
 *       2000 samples/s, as a sensor would be.
 *   cyclone_peer relay QOS TOPICS FROM_DOMAIN RATE QUIET_S [READERS]
 *       A stock driver in front of magnav: reads TOPICS (comma-separated, of
 *       gradiometer, magnetometer, vessel_nav) on FROM_DOMAIN with magnav's
 *       QoS (RELIABLE, TRANSIENT_LOCAL, KEEP_ALL) and writes every sample as it
 *       is, in the order taken, to the same topic on $MAGNAV_DOMAIN_ID with
 *       writer QoS QOS (default or sensor_data as above), at most RATE
 *       samples/s. Prints "ready" once each writer has matched READERS readers
 *       (default 1); ends once one came and the input's writers have left
 *       (`magnav replay` ended) with nothing more to take, or else QUIET_S
 *       seconds after the last sample, printing "relayed N samples".
 *   cyclone_peer expect-fixes FILE TIMEOUT_S
 *       Subscribes magnav/dipole_fix, prints "ready" once a writer (the
 *       service) is matched, and waits for one fix per row of FILE,
 *       the CSV `magnav invert` writes for the same samples; checks validity,
 *       reason, position and covariance bit for bit (the CSV has 17
 *       significant digits, so strtod gives back the very doubles).
 *   cyclone_peer collect-map-fixes OUT N TIMEOUT_S
 *       Subscribes magnav/map_fix (RELIABLE, TRANSIENT_LOCAL, KEEP_ALL),
 *       prints "ready" once a writer (magnav-matcher) is matched, and writes
 *       one line "stamp_ns,status" per fix received (status the MapFixStatus
 *       value as a number: an appended value this peer's IDL knows, e.g.
 *       MAP_FIX_STATUS_CONVERGING = 5, arrives as itself) to OUT until N
 *       came or TIMEOUT_S passed. Exit 0 iff N came.
 *
 * Exit codes: 0 ok, 1 the check failed, 2 usage or input error, 3 DDS error.
 */
#include <math.h>
#include <signal.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dds/dds.h"
#include "magnav.h"

#define MAX_COLUMNS 64
#define MAX_LINE 8192

/* ---- a minimal CSV table: '#' lines are parameters, then a header, then rows ---- */

typedef struct {
  int num_columns;
  char *names[MAX_COLUMNS];
  size_t num_rows;
  double *values;  /* num_rows x num_columns; an empty field is NaN */
  char **text;     /* num_rows x num_columns, the fields as written */
  double sigma_B;  /* "# sigma_B_T:" or NaN */
  double sigma_T;  /* "# sigma_T_Tpm:" or NaN */
} table_t;

static char *dup_trimmed(const char *s, size_t n) {
  while (n > 0 && (*s == ' ' || *s == '\t')) ++s, --n;
  while (n > 0 && (s[n - 1] == ' ' || s[n - 1] == '\t' || s[n - 1] == '\r' || s[n - 1] == '\n')) --n;
  char *out = malloc(n + 1);
  if (!out) exit(3);
  memcpy(out, s, n);
  out[n] = '\0';
  return out;
}

/* Splits a line at commas into at most MAX_COLUMNS fields; returns the count. */
static int split(const char *line, char **fields) {
  int n = 0;
  const char *start = line;
  for (const char *p = line;; ++p) {
    if (*p == ',' || *p == '\0' || *p == '\n' || *p == '\r') {
      if (n == MAX_COLUMNS) return -1;
      fields[n++] = dup_trimmed(start, (size_t)(p - start));
      if (*p != ',') break;
      start = p + 1;
    }
  }
  return n;
}

static double param_value(const char *line, const char *key) {
  const size_t k = strlen(key);
  if (strncmp(line + 1, " ", 1) != 0 || strncmp(line + 2, key, k) != 0 || line[2 + k] != ':') return NAN;
  return strtod(line + 3 + k, NULL);
}

static int read_table(const char *path, table_t *t) {
  memset(t, 0, sizeof *t);
  t->sigma_B = t->sigma_T = NAN;
  FILE *f = fopen(path, "r");
  if (!f) {
    fprintf(stderr, "cyclone_peer: cannot open %s\n", path);
    return -1;
  }
  char line[MAX_LINE];
  size_t capacity = 0;
  while (fgets(line, sizeof line, f)) {
    if (line[0] == '#') {
      const double b = param_value(line, "sigma_B_T"), tt = param_value(line, "sigma_T_Tpm");
      if (!isnan(b)) t->sigma_B = b;
      if (!isnan(tt)) t->sigma_T = tt;
      continue;
    }
    if (line[0] == '\n' || line[0] == '\0') continue;
    if (t->num_columns == 0) {
      t->num_columns = split(line, t->names);
      if (t->num_columns <= 0) break;
      continue;
    }
    char *fields[MAX_COLUMNS];
    const int n = split(line, fields);
    if (n != t->num_columns) {
      fprintf(stderr, "cyclone_peer: %s: a row has %d fields, the header %d\n", path, n, t->num_columns);
      fclose(f);
      return -1;
    }
    if (t->num_rows == capacity) {
      capacity = capacity ? 2 * capacity : 1024;
      t->values = realloc(t->values, capacity * (size_t)t->num_columns * sizeof(double));
      t->text = realloc(t->text, capacity * (size_t)t->num_columns * sizeof(char *));
      if (!t->values || !t->text) exit(3);
    }
    for (int c = 0; c < n; ++c) {
      char *end = NULL;
      double v = strtod(fields[c], &end);
      if (fields[c][0] == '\0' || *end != '\0') v = NAN;
      t->values[t->num_rows * (size_t)t->num_columns + (size_t)c] = v;
      t->text[t->num_rows * (size_t)t->num_columns + (size_t)c] = fields[c];
    }
    ++t->num_rows;
  }
  fclose(f);
  if (t->num_columns <= 0) {
    fprintf(stderr, "cyclone_peer: %s has no header\n", path);
    return -1;
  }
  return 0;
}

static int column(const table_t *t, const char *name) {
  for (int c = 0; c < t->num_columns; ++c) {
    if (strcmp(t->names[c], name) == 0) return c;
  }
  fprintf(stderr, "cyclone_peer: no column '%s'\n", name);
  exit(2);
}

static double value(const table_t *t, size_t row, int col) { return t->values[row * (size_t)t->num_columns + (size_t)col]; }
static const char *text(const table_t *t, size_t row, int col) { return t->text[row * (size_t)t->num_columns + (size_t)col]; }

static uint64_t seconds_to_nanos(double s) { return (isfinite(s) && s > 0.0) ? (uint64_t)llround(s * 1e9) : 0; }

/* Bit-for-bit equality (NaN equals NaN of the same bits; 0.0 differs from -0.0). */
static int same_bits(double a, double b) { return memcmp(&a, &b, sizeof a) == 0; }

/* The gradiometer sample magnav replay sends for row r with per-sensor seq. */
static void sample_of_row(const table_t *t, size_t r, uint64_t seq, magnav_msg_GradiometerSample *m) {
  static const char *pos[3] = {"sensor_x", "sensor_y", "sensor_z"};
  static const char *b[3] = {"B_x", "B_y", "B_z"};
  memset(m, 0, sizeof *m);
  m->sensor_id = (uint32_t)value(t, r, column(t, "sensor_id"));
  m->stamp_ns = seconds_to_nanos(value(t, r, column(t, "t")));
  m->seq = seq;
  for (int i = 0; i < 3; ++i) {
    m->sensor_position[i] = value(t, r, column(t, pos[i]));
    m->B[i] = value(t, r, column(t, b[i]));
  }
  for (int k = 0; k < 9; ++k) {
    char name[4] = {'T', (char)('0' + k / 3), (char)('0' + k % 3), '\0'};
    m->T[k] = value(t, r, column(t, name));
  }
  m->sigma_B = t->sigma_B;
  m->sigma_T = t->sigma_T;
}

static int same_sample(const magnav_msg_GradiometerSample *a, const magnav_msg_GradiometerSample *b) {
  if (a->sensor_id != b->sensor_id || a->stamp_ns != b->stamp_ns || a->seq != b->seq) return 0;
  for (int i = 0; i < 3; ++i) {
    if (!same_bits(a->sensor_position[i], b->sensor_position[i]) || !same_bits(a->B[i], b->B[i])) return 0;
  }
  for (int k = 0; k < 9; ++k) {
    if (!same_bits(a->T[k], b->T[k])) return 0;
  }
  return same_bits(a->sigma_B, b->sigma_B) && same_bits(a->sigma_T, b->sigma_T);
}

/* ---- DDS set-up ---- */

static dds_entity_t participant(void) {
  const char *env = getenv("MAGNAV_DOMAIN_ID");
  const dds_domainid_t domain = env ? (dds_domainid_t)strtoul(env, NULL, 10) : 0;
  const dds_entity_t pp = dds_create_participant(domain, NULL, NULL);
  if (pp < 0) {
    fprintf(stderr, "cyclone_peer: dds_create_participant: %s\n", dds_strretcode(-pp));
    exit(3);
  }
  return pp;
}

/* magnav's endpoint QoS (docs/PROTOCOL.md): reliable, XCDR1, and here
 * TRANSIENT_LOCAL so that samples written before this side matched the
 * writer are repaired from the writer's history (docs/INTEROP.md). */
static dds_qos_t *endpoint_qos(int transient_local, int keep_all) {
  dds_qos_t *q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(10));
  dds_qset_durability(q, transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
  if (keep_all) {
    dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
  } else {
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1000);
  }
  dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(q, 1, &xcdr1);
  return q;
}

/* A stock driver's writer QoS by name: NULL for magnav's own (caller
 * decides), Cyclone's default (no QoS given), or ROS 2's sensor-data QoS. */
typedef enum { QOS_MAGNAV, QOS_DEFAULT, QOS_SENSOR_DATA, QOS_UNKNOWN } qos_kind_t;

static qos_kind_t qos_kind(const char *name) {
  if (strcmp(name, "magnav") == 0) return QOS_MAGNAV;
  if (strcmp(name, "default") == 0) return QOS_DEFAULT;
  if (strcmp(name, "sensor_data") == 0) return QOS_SENSOR_DATA;
  return QOS_UNKNOWN;
}

static dds_entity_t stock_writer(dds_entity_t pp, dds_entity_t topic, qos_kind_t kind) {
  if (kind == QOS_MAGNAV) {
    dds_qos_t *q = endpoint_qos(1, 1);
    const dds_entity_t wr = dds_create_writer(pp, topic, q, NULL);
    dds_delete_qos(q);
    return wr;
  }
  if (kind == QOS_DEFAULT) return dds_create_writer(pp, topic, NULL, NULL);
  dds_qos_t *q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 5);
  const dds_entity_t wr = dds_create_writer(pp, topic, q, NULL);
  dds_delete_qos(q);
  return wr;
}

/* Sleeps until `n` samples fit a rate of `rate` per second since `start`. */
static void pace(dds_time_t start, size_t n, double rate) {
  if (rate <= 0) return;
  const dds_time_t due = start + (dds_duration_t)((double)n / rate * 1e9);
  const dds_time_t now = dds_time();
  if (due > now) dds_sleepfor(due - now);
}

/* The topic, with magnav's names or, when $MAGNAV_ROS2_NAMES=1, ROS 2's:
 * "rt/magnav/gradiometer" of type "magnav::msg::dds_::GradiometerSample_". */
static dds_entity_t topic_on(dds_entity_t pp, const dds_topic_descriptor_t *desc, const char *name) {
  char topic_name[128];
  const char *ros2 = getenv("MAGNAV_ROS2_NAMES");
  if (ros2 && strcmp(ros2, "1") == 0) {
    /* A copy of the descriptor with the other type name (its members are
     * const: copied bytewise into fresh memory, kept for the process). */
    char *type_name = malloc(128);
    dds_topic_descriptor_t *copy = malloc(sizeof *copy);
    if (!type_name || !copy) exit(3);
    const char *last = strrchr(desc->m_typename, ':');
    const size_t prefix = last ? (size_t)(last + 1 - desc->m_typename) : 0;
    snprintf(type_name, 128, "%.*sdds_::%s_", (int)prefix, desc->m_typename, desc->m_typename + prefix);
    memcpy(copy, desc, sizeof *copy);
    memcpy((char *)copy + offsetof(dds_topic_descriptor_t, m_typename), &type_name, sizeof type_name);
    desc = copy;
    snprintf(topic_name, sizeof topic_name, "rt/%s", name);
  } else {
    snprintf(topic_name, sizeof topic_name, "%s", name);
  }
  const dds_entity_t topic = dds_create_topic(pp, desc, topic_name, NULL, NULL);
  if (topic < 0) {
    fprintf(stderr, "cyclone_peer: dds_create_topic %s: %s\n", topic_name, dds_strretcode(-topic));
    exit(3);
  }
  return topic;
}

static dds_entity_t reader_on(dds_entity_t pp, const dds_topic_descriptor_t *desc, const char *name, int tl) {
  const dds_entity_t topic = topic_on(pp, desc, name);
  dds_qos_t *q = endpoint_qos(tl, 1);
  const dds_entity_t rd = dds_create_reader(pp, topic, q, NULL);
  dds_delete_qos(q);
  if (rd < 0) {
    fprintf(stderr, "cyclone_peer: dds_create_reader %s: %s\n", name, dds_strretcode(-rd));
    exit(3);
  }
  return rd;
}

#define TAKE_MAX 256

/* Takes what is there, waiting up to 100 ms for data; returns the count (loaned). */
static int take_some(dds_entity_t rd, dds_entity_t ws, void **samples, dds_sample_info_t *infos) {
  dds_waitset_wait(ws, NULL, 0, DDS_MSECS(100));
  memset(samples, 0, TAKE_MAX * sizeof(void *));
  return dds_take(rd, samples, infos, TAKE_MAX, TAKE_MAX);
}

static dds_entity_t waitset_for(dds_entity_t pp, dds_entity_t rd) {
  const dds_entity_t ws = dds_create_waitset(pp);
  const dds_entity_t rc = dds_create_readcondition(rd, DDS_ANY_STATE);
  dds_waitset_attach(ws, rc, rd);
  return ws;
}

/* A reader that leaves the moment it has its data may not have acknowledged
 * the last samples yet, and the writer then waits for it until its lease ends
 * (magnav replay: up to 10 s). Stay half a second to answer the heartbeats,
 * or less when rd (a reader; 0: none) has no writer left to answer (they
 * left: `magnav replay` ends once its readers acknowledged everything). */
static void linger_then_delete(dds_entity_t pp, dds_entity_t rd) {
  const dds_time_t end = dds_time() + DDS_MSECS(500);
  while (dds_time() < end) {
    dds_subscription_matched_status_t st;
    if (rd > 0 && dds_get_subscription_matched_status(rd, &st) == DDS_RETCODE_OK && st.current_count == 0) break;
    dds_sleepfor(DDS_MSECS(5));
  }
  dds_delete(pp);
}

/* Rows by key (sensor id and seq, or sensor id and time stamp), sorted for bsearch. */
typedef struct {
  uint32_t sensor;
  uint64_t second;
  size_t row;
} row_key_t;

static int row_key_cmp(const void *x, const void *y) {
  const row_key_t *a = x, *b = y;
  if (a->sensor != b->sensor) return a->sensor < b->sensor ? -1 : 1;
  if (a->second != b->second) return a->second < b->second ? -1 : 1;
  return 0;
}

/* The row of (sensor, second) among n sorted keys; n if none. */
static size_t find_row(const row_key_t *keys, size_t n, uint32_t sensor, uint64_t second) {
  const row_key_t k = {sensor, second, 0};
  const row_key_t *f = bsearch(&k, keys, n, sizeof *keys, row_key_cmp);
  return f ? f->row : n;
}

/* What a receiving mode counted. */
typedef struct {
  size_t received, differ, repeated, unknown;
} tally_t;

/* Takes samples from rd until every one of the n rows has one or timeout_s has
 * passed: key_of gives a sample's (sensor, second) key, same compares it with
 * its row (and may count); a row's first sample counts, later ones are
 * repeats, a sample of no row is unknown. seen[r] counts row r's samples. */
static tally_t collect(dds_entity_t rd, dds_entity_t ws, const row_key_t *keys, size_t n, double timeout_s,
                       int *seen, void (*key_of)(const void *sample, uint32_t *sensor, uint64_t *second),
                       int (*same)(const void *sample, size_t row, void *ctx), void *ctx) {
  tally_t c = {0, 0, 0, 0};
  const dds_time_t deadline = dds_time() + (dds_duration_t)(timeout_s * 1e9);
  void *samples[TAKE_MAX];
  dds_sample_info_t infos[TAKE_MAX];
  while (c.received < n && dds_time() < deadline) {
    const int got = take_some(rd, ws, samples, infos);
    for (int i = 0; i < got; ++i) {
      if (!infos[i].valid_data) continue;
      uint32_t sensor = 0;
      uint64_t second = 0;
      key_of(samples[i], &sensor, &second);
      const size_t r = find_row(keys, n, sensor, second);
      if (r == n) {
        ++c.unknown;
        continue;
      }
      if (seen[r]++) {
        ++c.repeated;
        continue;
      }
      ++c.received;
      if (!same(samples[i], r, ctx)) {
        if (c.differ == 0) fprintf(stderr, "cyclone_peer: the message of row %zu differs from the file\n", r + 1);
        ++c.differ;
      }
    }
    if (got > 0) dds_return_loan(rd, samples, got);
  }
  return c;
}

static int all_once(const tally_t *c, size_t n) {
  return c->received == n && c->differ == 0 && c->repeated == 0 && c->unknown == 0;
}

/* ---- modes ---- */

typedef struct {
  const table_t *t;
  const uint64_t *row_seq;
} samples_ctx_t;

static void sample_key(const void *sample, uint32_t *sensor, uint64_t *second) {
  const magnav_msg_GradiometerSample *m = sample;
  *sensor = m->sensor_id;
  *second = m->seq;
}

static int sample_same(const void *sample, size_t row, void *ctx) {
  const samples_ctx_t *c = ctx;
  magnav_msg_GradiometerSample expected;
  sample_of_row(c->t, row, c->row_seq[row], &expected);
  return same_sample(&expected, sample);
}

static int expect_samples(const char *path, double timeout_s, int transient_local) {
  table_t t;
  if (read_table(path, &t) != 0) return 2;
  const int c_id = column(&t, "sensor_id");
  /* Key of each row: (sensor id, per-sensor seq in file order), as replay numbers them. */
  uint64_t *row_seq = calloc(t.num_rows, sizeof(uint64_t));
  uint64_t *next_seq = calloc(1024, sizeof(uint64_t));
  row_key_t *keys = calloc(t.num_rows, sizeof(row_key_t));
  int *seen = calloc(t.num_rows, sizeof(int));
  if (!row_seq || !next_seq || !keys || !seen) return 3;
  for (size_t r = 0; r < t.num_rows; ++r) {
    const uint32_t id = (uint32_t)value(&t, r, c_id);
    if (id >= 1024) return 2;
    row_seq[r] = next_seq[id]++;
    keys[r] = (row_key_t){id, row_seq[r], r};
  }
  qsort(keys, t.num_rows, sizeof *keys, row_key_cmp);
  const dds_entity_t pp = participant();
  const dds_entity_t rd = reader_on(pp, &magnav_msg_GradiometerSample_desc, "magnav/gradiometer", transient_local);
  const dds_entity_t ws = waitset_for(pp, rd);
  printf("ready\n");
  fflush(stdout);

  samples_ctx_t ctx = {&t, row_seq};
  const tally_t c = collect(rd, ws, keys, t.num_rows, timeout_s, seen, sample_key, sample_same, &ctx);
  size_t first_missing = t.num_rows;
  for (size_t r = 0; r < t.num_rows && first_missing == t.num_rows; ++r) {
    if (!seen[r]) first_missing = r;
  }
  printf("received %zu of %zu, %zu differ, %zu repeated, %zu unknown", c.received, t.num_rows, c.differ, c.repeated,
         c.unknown);
  if (first_missing < t.num_rows) printf(" (first missing: sample %zu of the file)", first_missing);
  printf("\n");
  linger_then_delete(pp, rd);
  return all_once(&c, t.num_rows) ? 0 : 1;
}

static int send_samples(const char *path, qos_kind_t kind) {
  table_t t;
  if (read_table(path, &t) != 0) return 2;
  if (isnan(t.sigma_B) || isnan(t.sigma_T)) {
    fprintf(stderr, "cyclone_peer: %s has no '# sigma_B_T:' and '# sigma_T_Tpm:' lines\n", path);
    return 2;
  }
  const int c_id = column(&t, "sensor_id");
  const dds_entity_t pp = participant();
  const dds_entity_t topic = topic_on(pp, &magnav_msg_GradiometerSample_desc, "magnav/gradiometer");
  const dds_entity_t wr = stock_writer(pp, topic, kind);
  if (topic < 0 || wr < 0) {
    fprintf(stderr, "cyclone_peer: cannot create the writer\n");
    return 3;
  }
  dds_publication_matched_status_t st = {0};
  const dds_time_t deadline = dds_time() + DDS_SECS(30);
  while (st.current_count < 1 && dds_time() < deadline) {
    dds_get_publication_matched_status(wr, &st);
    dds_sleepfor(DDS_MSECS(10));
  }
  if (st.current_count < 1) {
    fprintf(stderr, "cyclone_peer: no reader of magnav/gradiometer within 30 s\n");
    return 1;
  }
  /* A stock driver's samples come at a sensor's pace: a burst into a
   * best-effort path would test the socket buffers, not magnav. */
  const double rate = kind == QOS_MAGNAV ? 0.0 : 2000.0;
  const dds_time_t start = dds_time();
  uint64_t seq[1024] = {0};
  for (size_t r = 0; r < t.num_rows; ++r) {
    const uint32_t id = (uint32_t)value(&t, r, c_id);
    if (id >= 1024) return 2;
    pace(start, r, rate);
    magnav_msg_GradiometerSample m;
    sample_of_row(&t, r, seq[id]++, &m);
    const dds_return_t rc = dds_write(wr, &m);
    if (rc != DDS_RETCODE_OK) {
      fprintf(stderr, "cyclone_peer: dds_write: %s\n", dds_strretcode(-rc));
      return 3;
    }
  }
  const dds_return_t acked = dds_wait_for_acks(wr, DDS_SECS(30));
  printf("sent %zu samples%s\n", t.num_rows, acked == DDS_RETCODE_OK ? "" : " (not all acknowledged)");
  dds_delete(pp);
  return acked == DDS_RETCODE_OK ? 0 : 1;
}

typedef struct {
  const table_t *t;
  int c_t, c_valid, c_reason, c_pos[3], c_cov[6];
  size_t valid;
} fixes_ctx_t;

static void fix_key(const void *sample, uint32_t *sensor, uint64_t *second) {
  const magnav_msg_DipoleFix *f = sample;
  *sensor = f->sensor_id;
  *second = f->stamp_ns;
}

static int fix_same(const void *sample, size_t r, void *ctx) {
  static const int kCovIndex[6] = {0, 1, 2, 4, 5, 8};
  fixes_ctx_t *c = ctx;
  const magnav_msg_DipoleFix *f = sample;
  const int want_valid = value(c->t, r, c->c_valid) == 1.0;
  int same = (f->valid != 0) == want_valid && strcmp(f->reason, text(c->t, r, c->c_reason)) == 0;
  if (want_valid) {
    ++c->valid;
    for (int k = 0; k < 3; ++k) same = same && same_bits(f->position[k], value(c->t, r, c->c_pos[k]));
    for (int k = 0; k < 6; ++k) same = same && same_bits(f->covariance[kCovIndex[k]], value(c->t, r, c->c_cov[k]));
  }
  return same;
}

/* Waits up to 30 s for a writer of `topic` to match the reader rd; 1 when one has. */
static int wait_for_writer(dds_entity_t rd, const char *topic) {
  dds_subscription_matched_status_t st = {0};
  const dds_time_t match_deadline = dds_time() + DDS_SECS(30);
  while (st.current_count < 1 && dds_time() < match_deadline) {
    dds_get_subscription_matched_status(rd, &st);
    dds_sleepfor(DDS_MSECS(10));
  }
  if (st.current_count < 1) fprintf(stderr, "cyclone_peer: no writer of %s within 30 s\n", topic);
  return st.current_count >= 1;
}

static int expect_fixes(const char *path, double timeout_s) {
  table_t t;
  if (read_table(path, &t) != 0) return 2;
  fixes_ctx_t ctx = {&t,
                     column(&t, "t"),
                     column(&t, "valid"),
                     column(&t, "reason"),
                     {column(&t, "dipole_x"), column(&t, "dipole_y"), column(&t, "dipole_z")},
                     {column(&t, "cov_xx"), column(&t, "cov_xy"), column(&t, "cov_xz"), column(&t, "cov_yy"),
                      column(&t, "cov_yz"), column(&t, "cov_zz")},
                     0};
  const int c_id = column(&t, "sensor_id");
  row_key_t *keys = calloc(t.num_rows, sizeof(row_key_t));
  int *seen = calloc(t.num_rows, sizeof(int));
  if (!keys || !seen) return 3;
  for (size_t r = 0; r < t.num_rows; ++r) {
    keys[r] = (row_key_t){(uint32_t)value(&t, r, c_id), seconds_to_nanos(value(&t, r, ctx.c_t)), r};
  }
  qsort(keys, t.num_rows, sizeof *keys, row_key_cmp);
  const dds_entity_t pp = participant();
  const dds_entity_t rd = reader_on(pp, &magnav_msg_DipoleFix_desc, "magnav/dipole_fix", 1);
  const dds_entity_t ws = waitset_for(pp, rd);
  /* Ready once the service's fix writer is matched: its TRANSIENT_LOCAL history
   * holds the last 1000 fixes per sensor, so a reader that matches only after a
   * 2001-sample burst gets the last 1000 (seen in CI after other tests had
   * slowed discovery). */
  if (!wait_for_writer(rd, "magnav/dipole_fix")) return 1;
  printf("ready\n");
  fflush(stdout);

  const tally_t c = collect(rd, ws, keys, t.num_rows, timeout_s, seen, fix_key, fix_same, &ctx);
  printf("received %zu of %zu fixes (%zu valid), %zu differ, %zu repeated, %zu unknown\n", c.received, t.num_rows,
         ctx.valid, c.differ, c.repeated, c.unknown);
  linger_then_delete(pp, rd);
  return all_once(&c, t.num_rows) ? 0 : 1;
}

/* ---- collect-map-fixes: magnav-matcher's fixes as a stock reader sees them ---- */

static int collect_map_fixes(const char *out_path, size_t n, double timeout_s) {
  FILE *out = fopen(out_path, "w");
  if (!out) {
    fprintf(stderr, "cyclone_peer: cannot write %s\n", out_path);
    return 2;
  }
  const dds_entity_t pp = participant();
  const dds_entity_t rd = reader_on(pp, &magnav_msg_MapFix_desc, "magnav/map_fix", 1);
  const dds_entity_t ws = waitset_for(pp, rd);
  if (!wait_for_writer(rd, "magnav/map_fix")) {
    fclose(out);
    return 1;
  }
  printf("ready\n");
  fflush(stdout);
  size_t received = 0;
  const dds_time_t deadline = dds_time() + (dds_duration_t)(timeout_s * 1e9);
  void *samples[TAKE_MAX];
  dds_sample_info_t infos[TAKE_MAX];
  while (received < n && dds_time() < deadline) {
    const int got = take_some(rd, ws, samples, infos);
    for (int i = 0; i < got; ++i) {
      if (!infos[i].valid_data) continue;
      const magnav_msg_MapFix *f = samples[i];
      fprintf(out, "%llu,%u\n", (unsigned long long)f->stamp_ns, (unsigned)f->status);
      ++received;
    }
    if (got > 0) dds_return_loan(rd, samples, got);
  }
  fclose(out);
  printf("received %zu of %zu map fixes\n", received, n);
  linger_then_delete(pp, rd);
  return received == n ? 0 : 1;
}

/* ---- relay: a stock writer in front of magnav ---- */

static volatile sig_atomic_t stop_requested = 0;
static void on_signal(int sig) {
  (void)sig;
  stop_requested = 1;
}

typedef struct {
  const char *name;
  const dds_topic_descriptor_t *desc;
} topic_kind_t;

static const topic_kind_t kRelayTopics[] = {
    {"gradiometer", &magnav_msg_GradiometerSample_desc},
    {"magnetometer", &magnav_msg_MagnetometerSample_desc},
    {"vessel_nav", &magnav_msg_VesselNav_desc},
};

static int relay(qos_kind_t kind, const char *topics, dds_domainid_t from, double rate, double quiet_s,
                 int min_readers) {
  if (kind == QOS_UNKNOWN) return 2;
  const char *env = getenv("MAGNAV_DOMAIN_ID");
  const dds_domainid_t to = env ? (dds_domainid_t)strtoul(env, NULL, 10) : 0;
  const dds_entity_t pp_in = dds_create_participant(from, NULL, NULL);
  const dds_entity_t pp_out = dds_create_participant(to, NULL, NULL);
  if (pp_in < 0 || pp_out < 0) {
    fprintf(stderr, "cyclone_peer: cannot create the participants on domains %u and %u\n", (unsigned)from,
            (unsigned)to);
    return 3;
  }
  dds_entity_t readers[8], writers[8];
  int n = 0;
  char list[256];
  snprintf(list, sizeof list, "%s", topics);
  for (char *name = strtok(list, ","); name; name = strtok(NULL, ",")) {
    const topic_kind_t *k = NULL;
    for (size_t i = 0; i < sizeof kRelayTopics / sizeof kRelayTopics[0]; ++i) {
      if (strcmp(kRelayTopics[i].name, name) == 0) k = &kRelayTopics[i];
    }
    if (!k || n == 8) {
      fprintf(stderr, "cyclone_peer: cannot relay topic '%s'\n", name);
      return 2;
    }
    char topic_name[64];
    snprintf(topic_name, sizeof topic_name, "magnav/%s", k->name);
    readers[n] = reader_on(pp_in, k->desc, topic_name, 1);
    writers[n] = stock_writer(pp_out, topic_on(pp_out, k->desc, topic_name), kind);
    if (writers[n] < 0) {
      fprintf(stderr, "cyclone_peer: cannot create the writer of %s\n", topic_name);
      return 3;
    }
    ++n;
  }
  const dds_entity_t ws = dds_create_waitset(pp_in);
  for (int i = 0; i < n; ++i) dds_waitset_attach(ws, dds_create_readcondition(readers[i], DDS_ANY_STATE), readers[i]);
  /* A volatile writer's samples before a reader matched are gone: ready once
   * every writer has min_readers readers (the service, recorders), at most 30 s. */
  for (int i = 0; i < n; ++i) {
    dds_publication_matched_status_t st = {0};
    const dds_time_t deadline = dds_time() + DDS_SECS(30);
    while ((int)st.current_count < min_readers && dds_time() < deadline) {
      dds_get_publication_matched_status(writers[i], &st);
      dds_sleepfor(DDS_MSECS(10));
    }
    if ((int)st.current_count < min_readers) {
      fprintf(stderr, "cyclone_peer: too few readers of the relayed topic %d on domain %u within 30 s\n", i, (unsigned)to);
      return 1;
    }
  }
  signal(SIGTERM, on_signal);
  signal(SIGINT, on_signal);
  printf("ready\n");
  fflush(stdout);
  size_t relayed = 0;
  dds_time_t start = 0, last = 0;
  void *samples[TAKE_MAX];
  dds_sample_info_t infos[TAKE_MAX];
  int empty_after_gone = 0;
  while (!stop_requested) {
    /* The input's writers (`magnav replay`, which ends once every sample was
     * acknowledged) have left: what they sent is here or on its way. Looked at
     * before taking, so a sample taken after it cannot be missed. */
    int writers_gone = relayed > 0;
    for (int i = 0; i < n && writers_gone; ++i) {
      dds_subscription_matched_status_t st;
      if (dds_get_subscription_matched_status(readers[i], &st) != DDS_RETCODE_OK || st.current_count > 0) writers_gone = 0;
    }
    dds_waitset_wait(ws, NULL, 0, DDS_MSECS(100));
    int got_any = 0;
    for (int i = 0; i < n; ++i) {
      memset(samples, 0, sizeof samples);
      const int got = dds_take(readers[i], samples, infos, TAKE_MAX, TAKE_MAX);
      for (int j = 0; j < got; ++j) {
        if (!infos[j].valid_data) continue;
        if (relayed == 0) start = dds_time();
        pace(start, relayed, rate);
        if (dds_write(writers[i], samples[j]) != DDS_RETCODE_OK) {
          fprintf(stderr, "cyclone_peer: dds_write failed\n");
          return 3;
        }
        ++relayed;
        got_any = 1;
      }
      if (got > 0) dds_return_loan(readers[i], samples, got);
    }
    if (got_any) last = dds_time();
    /* Ends after two empty takes (>= 100 ms) once the writers left, else
     * quiet_s after the last sample. */
    empty_after_gone = writers_gone && !got_any ? empty_after_gone + 1 : 0;
    if (empty_after_gone >= 2) break;
    if (relayed > 0 && !got_any && dds_time() - last > (dds_duration_t)(quiet_s * 1e9)) break;
  }
  for (int i = 0; i < n; ++i) dds_wait_for_acks(writers[i], DDS_SECS(10));
  printf("relayed %zu samples\n", relayed);
  fflush(stdout);
  linger_then_delete(pp_out, 0);
  dds_delete(pp_in);
  return 0;
}

int main(int argc, char **argv) {
  if (argc >= 4 && strcmp(argv[1], "expect-samples") == 0) {
    const int tl = !(argc == 5 && strcmp(argv[4], "volatile") == 0);
    return expect_samples(argv[2], atof(argv[3]), tl);
  }
  if ((argc == 3 || argc == 4) && strcmp(argv[1], "send-samples") == 0) {
    const qos_kind_t kind = argc == 4 ? qos_kind(argv[3]) : QOS_MAGNAV;
    if (kind == QOS_UNKNOWN) return 2;
    return send_samples(argv[2], kind);
  }
  if ((argc == 7 || argc == 8) && strcmp(argv[1], "relay") == 0) {
    return relay(qos_kind(argv[2]), argv[3], (dds_domainid_t)strtoul(argv[4], NULL, 10), atof(argv[5]),
                 atof(argv[6]), argc == 8 ? atoi(argv[7]) : 1);
  }
  if (argc == 4 && strcmp(argv[1], "expect-fixes") == 0) return expect_fixes(argv[2], atof(argv[3]));
  if (argc == 5 && strcmp(argv[1], "collect-map-fixes") == 0) {
    return collect_map_fixes(argv[2], (size_t)strtoul(argv[3], NULL, 10), atof(argv[4]));
  }
  fprintf(stderr,
          "usage: cyclone_peer expect-samples FILE TIMEOUT_S [volatile] | send-samples FILE "
          "[magnav|default|sensor_data] | expect-fixes FILE TIMEOUT_S | collect-map-fixes OUT N TIMEOUT_S | "
          "relay default|sensor_data TOPICS FROM_DOMAIN RATE QUIET_S [READERS]\n");
  return 2;
}
