/* A camera process in C: publishes recorded camera outputs from a folder (vo.csv,
 * detections3d.csv, det2d.txt, imu.csv — the files `dash2sim record` reads, docs/cli.md) over
 * dash2sim's shared-memory bridge at their frame rate, through the C ABI
 * (adapters/camera-c/include/dash2sim_camera.h), then prints "N frames published".
 *
 * The same program as examples/src/bin/camera_files.rs (Rust) and
 * adapters/python/examples/camera_files.py: `dash2sim record --camera` logs the same bytes
 * from each (adapters/cli/tests/camera_publishers.rs).
 *
 * Build (docs/bridge.md):
 *   cargo build --release -p dash2sim-camera
 *   cc -std=c11 -O2 -Wall -Wextra -ffp-contract=off -Iadapters/camera-c/include \
 *      examples/camera-c/camera_files.c -Ltarget/release -ldash2sim_camera \
 *      -Wl,-rpath,$PWD/target/release -lm -o camera_files_c
 * Run:
 *   camera_files_c DRIVE_DIR [--prefix P] [--speedup X] [--file-times]
 */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "dash2sim_camera.h"

typedef struct {
  uint64_t frame;
  double t;
  uint32_t session;
  double position[3];
  double wxyz[4];
} vo_row;

typedef struct {
  uint64_t frame;
  double t;
  d2s_detection3d box;
} box3d_row;

typedef struct {
  uint64_t frame;
  d2s_detection2d box;
} box2d_row;

typedef struct {
  double t;
  float gyro[3], accel[3];
} imu_row;

/* A growing array of `size`-byte rows. */
typedef struct {
  void *rows;
  size_t count, capacity, size;
} table;

static void *table_push(table *t) {
  if (t->count == t->capacity) {
    size_t capacity = t->capacity ? 2 * t->capacity : 256;
    void *rows = realloc(t->rows, capacity * t->size);
    if (!rows) {
      fprintf(stderr, "camera_files_c: out of memory\n");
      exit(1);
    }
    t->rows = rows;
    t->capacity = capacity;
  }
  return (char *)t->rows + t->size * t->count++;
}

/* Splits `line` at commas into at most `max` fields (empty fields kept); their number. */
static size_t split(char *line, char **fields, size_t max) {
  size_t n = 0;
  line[strcspn(line, "\r\n")] = '\0';
  for (char *p = line; n < max;) {
    fields[n++] = p;
    char *comma = strchr(p, ',');
    if (!comma) break;
    *comma = '\0';
    p = comma + 1;
  }
  return n;
}

static int number(const char *text, double *out) {
  char *end;
  errno = 0;
  *out = strtod(text, &end);
  return end != text && *end == '\0' && errno == 0 && isfinite(*out);
}

static void bad_line(const char *path, size_t line, const char *what) {
  fprintf(stderr, "camera_files_c: %s:%zu: %s\n", path, line, what);
  exit(1);
}

/* Opens dir/name; NULL when the file does not exist (nothing of its kind is published). */
static FILE *open_in(const char *dir, const char *name, char *path, size_t size) {
  snprintf(path, size, "%s/%s", dir, name);
  FILE *f = fopen(path, "r");
  if (!f && errno != ENOENT) {
    fprintf(stderr, "camera_files_c: %s: %s\n", path, strerror(errno));
    exit(1);
  }
  return f;
}

static table read_vo(const char *dir) {
  table t = {NULL, 0, 0, sizeof(vo_row)};
  char path[4096], line[1024], *f[11];
  FILE *file = open_in(dir, "vo.csv", path, sizeof path);
  if (!file) return t;
  for (size_t n = 1; fgets(line, sizeof line, file); n++) {
    if (line[0] == '#' || line[0] == '\n' || strncmp(line, "frame,", 6) == 0) continue;
    double v[10];
    if (split(line, f, 11) != 10) bad_line(path, n, "expected frame,t_s,x,y,z,qx,qy,qz,qw,session");
    for (int k = 0; k < 10; k++)
      if (!number(f[k], &v[k])) bad_line(path, n, "a field is not a finite number");
    vo_row *row = table_push(&t);
    row->frame = (uint64_t)v[0];
    row->t = v[1];
    memcpy(row->position, &v[2], sizeof row->position);
    double wxyz[4] = {v[8], v[5], v[6], v[7]};
    memcpy(row->wxyz, wxyz, sizeof wxyz);
    row->session = (uint32_t)v[9];
  }
  fclose(file);
  return t;
}

static table read_imu(const char *dir) {
  table t = {NULL, 0, 0, sizeof(imu_row)};
  char path[4096], line[1024], *f[8];
  FILE *file = open_in(dir, "imu.csv", path, sizeof path);
  if (!file) return t;
  for (size_t n = 1; fgets(line, sizeof line, file); n++) {
    if (line[0] == '#' || line[0] == '\n' || strncmp(line, "t_s,", 4) == 0) continue;
    double v[7];
    if (split(line, f, 8) != 7) bad_line(path, n, "expected t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z");
    for (int k = 0; k < 7; k++)
      if (!number(f[k], &v[k])) bad_line(path, n, "a field is not a finite number");
    imu_row *row = table_push(&t);
    row->t = v[0];
    for (int k = 0; k < 3; k++) {
      row->gyro[k] = (float)v[1 + k];
      row->accel[k] = (float)v[4 + k];
    }
  }
  fclose(file);
  return t;
}

static table read_boxes3d(const char *dir) {
  table t = {NULL, 0, 0, sizeof(box3d_row)};
  char path[4096], line[1024], *f[15];
  FILE *file = open_in(dir, "detections3d.csv", path, sizeof path);
  if (!file) return t;
  for (size_t n = 1; fgets(line, sizeof line, file); n++) {
    if (line[0] == '\n' || strncmp(line, "frame,", 6) == 0) continue;
    size_t count = split(line, f, 15);
    if (count != 11 && count != 14) bad_line(path, n, "expected 11 or 14 columns");
    double v[14] = {0};
    for (size_t k = 0; k < count; k++)
      if (k != 2 && !(k >= 11 && f[k][0] == '\0') && !number(f[k], &v[k]))
        bad_line(path, n, "a field is not a finite number");
    box3d_row *row = table_push(&t);
    row->frame = (uint64_t)v[0];
    row->t = v[1];
    int32_t class_id = d2s_class_id(f[2]);
    row->box.class_ = class_id < 0 ? UINT16_MAX : (uint16_t)class_id;
    row->box.reserved = 0;
    for (int k = 0; k < 7; k++) row->box.bbox[k] = (float)v[3 + k];
    row->box.score = (float)v[10];
    for (int k = 0; k < 3; k++) row->box.covariance[k] = (float)v[11 + k];
  }
  fclose(file);
  return t;
}

static table read_boxes2d(const char *dir) {
  table t = {NULL, 0, 0, sizeof(box2d_row)};
  char path[4096], line[1024], *f[12];
  FILE *file = open_in(dir, "det2d.txt", path, sizeof path);
  if (!file) return t;
  for (size_t n = 1; fgets(line, sizeof line, file); n++) {
    if (line[0] == '\n') continue;
    double v[7];
    if (split(line, f, 12) < 7) bad_line(path, n, "expected at least 7 columns");
    for (int k = 0; k < 7; k++)
      if (!number(f[k], &v[k])) bad_line(path, n, "a field is not a number");
    box2d_row *row = table_push(&t);
    row->frame = (uint64_t)v[0];
    row->box = (d2s_detection2d){.class_ = 0, .reserved = 0, .score = (float)v[6],
                                 .bbox = {(float)v[2], (float)v[3], (float)v[4], (float)v[5]}};
  }
  fclose(file);
  return t;
}

static int64_t micros(double t_s) { return (int64_t)llround(t_s * 1e6); }

static void sleep_until(const struct timespec *start, double offset_s) {
  struct timespec due = *start;
  due.tv_sec += (time_t)floor(offset_s);
  due.tv_nsec += (long)((offset_s - floor(offset_s)) * 1e9);
  if (due.tv_nsec >= 1000000000L) {
    due.tv_sec += 1;
    due.tv_nsec -= 1000000000L;
  }
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &due, NULL) == EINTR) {
  }
}

static void check(int32_t status) {
  if (status != D2S_OK) {
    fprintf(stderr, "camera_files_c: %s\n", d2s_last_error());
    exit(1);
  }
}

static void too_many(uint64_t frame) {
  fprintf(stderr, "camera_files_c: frame %llu has more than %d detections\n", (unsigned long long)frame,
          D2S_MAX_DETECTIONS);
  exit(1);
}

int main(int argc, char **argv) {
  const char *dir = NULL, *prefix = "dash2sim/camera";
  double speedup = 1.0;
  int file_times = 0;
  for (int i = 1; i < argc; i++) {
    if (strcmp(argv[i], "--prefix") == 0 && i + 1 < argc) prefix = argv[++i];
    else if (strcmp(argv[i], "--speedup") == 0 && i + 1 < argc) speedup = atof(argv[++i]);
    else if (strcmp(argv[i], "--file-times") == 0) file_times = 1;
    else if (argv[i][0] != '-' && !dir) dir = argv[i];
    else {
      fprintf(stderr, "usage: camera_files_c DRIVE_DIR [--prefix P] [--speedup X] [--file-times]\n");
      return 2;
    }
  }
  if (!dir || !(speedup > 0)) {
    fprintf(stderr, "usage: camera_files_c DRIVE_DIR [--prefix P] [--speedup X] [--file-times]\n");
    return 2;
  }
  table vo = read_vo(dir), boxes3d = read_boxes3d(dir), boxes2d = read_boxes2d(dir), imu = read_imu(dir);
  const imu_row *samples = imu.rows;
  const vo_row *poses = vo.rows;
  const box3d_row *b3 = boxes3d.rows;
  const box2d_row *b2 = boxes2d.rows;

  int32_t status;
  d2s_publisher *camera = d2s_publisher_open(prefix, false, &status);
  if (!camera) {
    fprintf(stderr, "camera_files_c: %s\n", d2s_last_error());
    return 1;
  }
  struct timespec start;
  clock_gettime(CLOCK_MONOTONIC, &start);
  int64_t device_start = d2s_device_now_us();
  /* The frames in order: a merge of the VO's and the 3D detections' frame numbers (both
   * files are in frame order); the 2D detections follow their frame. */
  size_t i = 0, j = 0, k = 0, m = 0, published = 0;
  double first = -1;
  while (i < vo.count || j < boxes3d.count) {
    uint64_t frame = i < vo.count ? poses[i].frame : UINT64_MAX;
    if (j < boxes3d.count && b3[j].frame < frame) frame = b3[j].frame;
    int has_pose = i < vo.count && poses[i].frame == frame;
    double t_s = has_pose ? poses[i].t : b3[j].t;
    if (first < 0) first = t_s;
    sleep_until(&start, (t_s - first) / speedup);
    /* The IMU samples stamped up to this frame (a camera reads its IMU's FIFO once a frame). */
    for (; m < imu.count && samples[m].t <= t_s; m++) {
      int64_t t_imu = file_times ? micros(samples[m].t) : device_start + (micros(samples[m].t) - micros(first));
      check(d2s_publish_imu(camera, t_imu, samples[m].gyro, samples[m].accel));
    }
    int64_t t = file_times ? micros(t_s) : device_start + (micros(t_s) - micros(first));

    check(d2s_publish_frame(camera, frame, t, 0));
    if (has_pose) {
      double rotation[9];
      d2s_rotation_from_quaternion(poses[i].wxyz, rotation);
      check(d2s_publish_vo(camera, frame, t, poses[i].session, poses[i].position, rotation));
      i++;
    }
    d2s_detection3d items3[D2S_MAX_DETECTIONS];
    size_t n3 = 0;
    for (; j < boxes3d.count && b3[j].frame == frame; j++) {
      if (n3 == D2S_MAX_DETECTIONS) too_many(frame);
      items3[n3++] = b3[j].box;
    }
    check(d2s_publish_detections3d(camera, frame, t, items3, n3));
    d2s_detection2d items2[D2S_MAX_DETECTIONS];
    size_t n2 = 0;
    for (; k < boxes2d.count && b2[k].frame < frame; k++) {
    }
    for (; k < boxes2d.count && b2[k].frame == frame; k++) {
      if (n2 == D2S_MAX_DETECTIONS) too_many(frame);
      items2[n2++] = b2[k].box;
    }
    check(d2s_publish_detections2d(camera, frame, t, items2, n2));
    published++;
  }
  /* Samples live in the publisher's shared memory: closing it at once could take the last
   * frame's away before the logger has read them. */
  struct timespec linger = {0, 500000000L};
  nanosleep(&linger, NULL);
  d2s_publisher_close(camera);
  free(vo.rows);
  free(boxes3d.rows);
  free(boxes2d.rows);
  free(imu.rows);
  printf("%zu frames published\n", published);
  return 0;
}
