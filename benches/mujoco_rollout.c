// C rollout of an exported scene (`dvrk export mjcf`) in MuJoCo on the section 4.3 tracking test,
// with the PID of crates/dvrk-sim/src/control.rs (conditional integration, integral cap
// effort_limit / ki, effort clamp) computed in C between steps, so the timing is MuJoCo's, not
// Python's. Built and run by benches/mujoco_rtf.py; usage: mujoco_rollout FILE.xml DURATION_S.
// Prints one JSON object: steps, dt (s), wall_time (s, the step loop with controller and
// statistics, as `dvrk sim` times its own), real_time_factor, max_closure_error (m), rms (per
// actuated joint, rad or m). Drive data: the `dvrk:ARM/joint` custom numerics (see
// crates/dvrk-sim/src/mjcf.rs, DRIVE_FIELDS).
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <mujoco/mujoco.h>

enum { C, B, KP, KI, KD, LIM, POS, HOME, AMP, FREQ, LO, HI, NFIELD };

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

int main(int argc, char** argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s FILE.xml DURATION_S\n", argv[0]);
    return 2;
  }
  char err[1000] = "";
  mjModel* m = mj_loadXML(argv[1], NULL, err, sizeof err);
  if (!m) {
    fprintf(stderr, "error: %s: %s\n", argv[1], err);
    return 1;
  }
  mjData* d = mj_makeData(m);
  int n = m->nu;
  double* p = calloc((size_t)n * NFIELD, sizeof(double));
  int *qa = calloc(n, sizeof(int)), *sa = calloc(m->nsite, sizeof(int)), *sb = calloc(m->nsite, sizeof(int));
  double *integral = calloc(n, sizeof(double)), *qprev = calloc(n, sizeof(double)), *qd = calloc(n, sizeof(double));
  double *sumsq = calloc(n, sizeof(double));
  for (int i = 0; i < n; i++) {
    char name[300];
    snprintf(name, sizeof name, "dvrk:%s", mj_id2name(m, mjOBJ_ACTUATOR, i));
    int id = mj_name2id(m, mjOBJ_NUMERIC, name);
    if (id < 0 || m->numeric_size[id] != NFIELD) {
      fprintf(stderr, "error: %s: no %d-value custom numeric %s\n", argv[1], NFIELD, name);
      return 1;
    }
    memcpy(p + i * NFIELD, m->numeric_data + m->numeric_adr[id], NFIELD * sizeof(double));
    qa[i] = m->jnt_qposadr[m->actuator_trnid[2 * i]];
  }
  // Loop closures: site pairs ARM/c:a, ARM/c:b.
  int npair = 0;
  for (int i = 0; i < m->nsite; i++) {
    const char* s = mj_id2name(m, mjOBJ_SITE, i);
    size_t len = s ? strlen(s) : 0;
    if (len > 2 && strcmp(s + len - 2, ":a") == 0) {
      char other[300];
      snprintf(other, sizeof other, "%.*s:b", (int)(len - 2), s);
      int j = mj_name2id(m, mjOBJ_SITE, other);
      if (j >= 0) {
        sa[npair] = i;
        sb[npair++] = j;
      }
    }
  }
  double dt = m->opt.timestep, duration = atof(argv[2]);
  long steps = lround(duration / dt);
  if (steps < 1) steps = 1;
  mj_forward(m, d);
  for (int i = 0; i < n; i++) qprev[i] = (d->qpos[qa[i]] - p[i * NFIELD + B]) / p[i * NFIELD + C];
  double max_gap = 0.0, t0 = now();
  for (long s = 0; s < steps; s++) {
    double t = (s + 1) * dt;
    for (int i = 0; i < n; i++) {
      const double* f = p + i * NFIELD;
      double w = 2.0 * M_PI * f[FREQ];
      double qr = fmin(fmax(f[HOME] + f[AMP] * sin(w * t), f[LO]), f[HI]);
      double qdr = f[AMP] * w * cos(w * t);
      double q = (d->qpos[qa[i]] - f[B]) / f[C];
      double e = qr - q;
      double unsat = f[KP] * e + f[KI] * (integral[i] + e * dt) + f[KD] * (qdr - qd[i]);
      double tau = f[LIM] > 0.0 ? fmin(fmax(unsat, -f[LIM]), f[LIM]) : unsat;
      int saturated = tau != unsat && (unsat >= 0.0) == (e >= 0.0);
      if (!saturated) {
        integral[i] += e * dt;
        if (f[LIM] > 0.0 && f[KI] > 0.0) integral[i] = fmin(fmax(integral[i], -f[LIM] / f[KI]), f[LIM] / f[KI]);
      }
      d->ctrl[i] = f[POS] != 0.0 ? 0.0 : tau;
    }
    mj_step(m, d);
    for (int i = 0; i < n; i++) {
      const double* f = p + i * NFIELD;
      double w = 2.0 * M_PI * f[FREQ];
      double qr = fmin(fmax(f[HOME] + f[AMP] * sin(w * t), f[LO]), f[HI]);
      double q = (d->qpos[qa[i]] - f[B]) / f[C];
      qd[i] = (q - qprev[i]) / dt;
      qprev[i] = q;
      sumsq[i] += (q - qr) * (q - qr);
    }
    // mj_step computes positions before it integrates: site_xpos lags qpos by one step.
    for (int k = 0; k < npair; k++) {
      const double *a = d->site_xpos + 3 * sa[k], *b = d->site_xpos + 3 * sb[k];
      double gap = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
      if (gap > max_gap) max_gap = gap;
    }
  }
  double wall = now() - t0;
  printf("{\"steps\": %ld, \"dt\": %.17g, \"wall_time\": %.17g, \"real_time_factor\": %.17g, \"max_closure_error\": %.17g, \"rms\": [",
         steps, dt, wall, steps * dt / wall, max_gap);
  for (int i = 0; i < n; i++) printf("%s%.17g", i ? ", " : "", sqrt(sumsq[i] / steps));
  printf("]}\n");
  mj_deleteData(d);
  mj_deleteModel(m);
  return 0;
}
