// o2m.schutte: an actuator MuJoCo plugin that is OpenSim's Schutte1993Muscle_Deprecated
// (Schutte 1992; OpenSim's Schutte1993Muscle_Deprecated.cpp): an elastic tendon in series with a
// pennated fibre, whose activation and fibre length are the instance's state. MuJoCo's muscle has
// a rigid tendon and no fibre state, so it cannot follow the tendon force's lag behind activation,
// nor a passive fibre that stays long after a stretch (the fibre shortens only under active force).
//
// Per step: `compute` (mj_fwdActuation) gives the tendon's pull at the state and the actuator's
// length, as OpenSim's computeActuation does; `advance` (after MuJoCo's integrator) steps the state
// over the time step: the activation exactly for the step's constant control, the fibre length by
// backward Euler on the muscle-tendon length reached at the step's end (the fibre is far stiffer
// than a 2-ms step: its time constant is tens of microseconds, which OpenSim's error-controlled
// integrator resolves and an explicit step could not). The curves come as uniform tables in the
// instance's config (o2m.mj.schutte_plugin writes them). Built by o2m.mj.plugins.build.
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <mujoco/mujoco.h>

// Schutte's force-velocity constants (calcFiberVelocity).
#define KV 0.15
#define SLOPE_K 0.13
#define FMAX 1.4

typedef struct {
  double lo, step; int n; double* y;   // y at lo + k * step, k = 0..n-1; linear beyond the ends
} Table;

typedef struct {
  int actuator, out, tendon;
  double f0, l0, lts, sina0, time_scale, act1, act2, damping;
  Table tendon_f, active_fl, passive_fl;   // strain -> F/F0; fibre length / l0 -> F/F0 (twice)
} Muscle;

static const char* ATTRS[] = {"f0", "l0", "lts", "sina0", "time_scale", "activation1", "activation2", "damping",
                              "activation0", "fibre0", "tendon_curve", "active_curve", "passive_curve"};

static int parse(const char* s, Table* t) {  // "lo step y0 y1 ..."
  char* e; int cap = 64, n = 0; double v[2];
  for (int i = 0; i < 2; i++) { v[i] = strtod(s, &e); if (e == s) return -1; s = e; }
  t->lo = v[0]; t->step = v[1];
  t->y = (double*)malloc(sizeof(double) * cap);
  while (1) {
    double x = strtod(s, &e); if (e == s) break; s = e;
    if (n == cap) { cap *= 2; t->y = (double*)realloc(t->y, sizeof(double) * cap); }
    t->y[n++] = x;
  }
  t->n = n;
  return n >= 2 && t->step > 0 ? 0 : -1;
}
static double value(const Table* t, double x) {
  double u = (x - t->lo) / t->step;
  int k = (int)floor(u);
  if (k < 0) k = 0;
  if (k > t->n - 2) k = t->n - 2;
  double w = u - k;
  return t->y[k] + w * (t->y[k + 1] - t->y[k]);
}
static double config(const mjModel* m, int instance, const char* key) {
  return atof(mj_getPluginConfig(m, instance, key));
}

// Tendon force / F0 at muscle-tendon length L (m) and fibre length lf (m); *cos_pennation out.
static double tendon_force(const Muscle* u, double L, double lf, double* ca) {
  double s = u->sina0 * u->l0 / lf;
  if (s > 1 - 1e-12) s = 1 - 1e-12;  // pennation at 90 degrees: OpenSim's special case, not reached here
  *ca = sqrt(1 - s * s);
  double strain = (L - lf * *ca) / u->lts - 1.0;
  return strain > 0 ? value(&u->tendon_f, strain) : 0.0;
}

// Fibre velocity (m/s) at activation a, fibre length lf (m), muscle-tendon length L (m):
// Schutte's inverse force-velocity relation with damping (calcFiberVelocity), unnormalized.
static double fibre_velocity(const Muscle* u, double a, double lf, double L) {
  double ca, x = lf / u->l0, d = u->damping;
  double ft = tendon_force(u, L, lf, &ca);
  double fa = value(&u->active_fl, x); if (fa < 0) fa = 0;
  double fv = ft / ca - value(&u->passive_fl, x);
  if (fv < 0) fv = 0;  // computeActuation clamps the velocity-dependent force at zero
  double v, b, c, af = a * fa;
  if (fv < af) {  // (calcFiberVelocity's branch for fv < -damping is unreachable: fv >= 0 here)
    c = KV * (fv - af) / d;
    b = -KV * (fv / KV + af + d) / d;
    v = (-b - sqrt(b * b - 4 * c)) / 2.0;
  } else {
    c = -(SLOPE_K * KV / (d * (KV + 1))) * (fv - af);
    b = -(fv / d - FMAX * af / d - SLOPE_K * KV / (KV + 1));
    v = (-b + sqrt(b * b - 4 * c)) / 2.0;
  }
  return v * u->l0 / u->time_scale;
}

// Backward Euler: the fibre length x with x = lf + h * v(a, x, L), by bracketed regula falsi
// (Illinois). The residual rises with x wherever the tendon is stiffer than the active
// force-length slope, which is everywhere the tables reach in practice.
static double step_fibre(const Muscle* u, double a, double lf, double L, double h) {
  double lo = lf, glo = -h * fibre_velocity(u, a, lf, L);
  if (glo == 0) return lf;
  double dir = glo < 0 ? 1.0 : -1.0, width = fabs(glo) + 1e-9 * u->l0, hi, ghi;
  for (int k = 0; k < 60; k++) {  // expand until the residual changes sign
    hi = lf + dir * width;
    if (hi < 1e-6 * u->l0) hi = 1e-6 * u->l0;
    ghi = hi - lf - h * fibre_velocity(u, a, hi, L);
    if ((ghi > 0) != (glo > 0)) break;
    lo = hi; glo = ghi; width *= 2;
  }
  int side = 0;
  for (int k = 0; k < 60; k++) {
    double x = (lo * ghi - hi * glo) / (ghi - glo);
    double g = x - lf - h * fibre_velocity(u, a, x, L);
    if (fabs(g) < 1e-13 * u->l0 || fabs(hi - lo) < 1e-14 * u->l0) return x;
    if ((g > 0) == (ghi > 0)) { hi = x; ghi = g; if (side == -1) glo /= 2; side = -1; }
    else { lo = x; glo = g; if (side == 1) ghi /= 2; side = 1; }
  }
  return (lo + hi) / 2;
}

static int nstate(const mjModel* m, int instance) { return 2; }  // activation, fibre length (m)

static int init(const mjModel* m, mjData* d, int instance) {
  Muscle* u = (Muscle*)calloc(1, sizeof(Muscle));
  u->actuator = -1;
  for (int i = 0; i < m->nu; i++) if (m->actuator_plugin[i] == instance) u->actuator = i;
  if (u->actuator < 0 || m->actuator_trntype[u->actuator] != mjTRN_TENDON) {
    mju_warning("o2m.schutte: instance %d is not the plugin of a tendon actuator", instance);
    free(u); return -1;
  }
  u->out = m->actuator_outadr[u->actuator];
  u->tendon = m->actuator_trnid[2 * u->actuator];
  u->f0 = config(m, instance, "f0"); u->l0 = config(m, instance, "l0"); u->lts = config(m, instance, "lts");
  u->sina0 = config(m, instance, "sina0"); u->time_scale = config(m, instance, "time_scale");
  u->act1 = config(m, instance, "activation1"); u->act2 = config(m, instance, "activation2");
  u->damping = config(m, instance, "damping");
  if (parse(mj_getPluginConfig(m, instance, "tendon_curve"), &u->tendon_f) ||
      parse(mj_getPluginConfig(m, instance, "active_curve"), &u->active_fl) ||
      parse(mj_getPluginConfig(m, instance, "passive_curve"), &u->passive_fl) ||
      u->l0 <= 0 || u->lts <= 0 || u->time_scale <= 0 || u->damping <= 0) {
    mju_warning("o2m.schutte: instance %d has an invalid config", instance);
    free(u->tendon_f.y); free(u->active_fl.y); free(u->passive_fl.y); free(u); return -1;
  }
  d->plugin_data[instance] = (uintptr_t)u;
  return 0;
}
static void destroy(mjData* d, int instance) {
  Muscle* u = (Muscle*)d->plugin_data[instance];
  if (!u) return;
  free(u->tendon_f.y); free(u->active_fl.y); free(u->passive_fl.y); free(u);
  d->plugin_data[instance] = 0;
}
static void reset(const mjModel* m, mjtNum* state, void* data, int instance) {
  state[0] = config(m, instance, "activation0");
  state[1] = config(m, instance, "fibre0");
}
static void compute(const mjModel* m, mjData* d, int instance, int bit) {
  Muscle* u = (Muscle*)d->plugin_data[instance];
  const mjtNum* s = d->plugin_state + m->plugin_stateadr[instance];
  double ca;
  d->actuator_force[u->out] = -u->f0 * tendon_force(u, d->actuator_length[u->out], s[1], &ca);
}
static void advance(const mjModel* m, mjData* d, int instance) {
  Muscle* u = (Muscle*)d->plugin_data[instance];
  mjtNum* s = d->plugin_state + m->plugin_stateadr[instance];
  double h = m->opt.timestep, e = d->ctrl[u->actuator];
  if (e < 0) e = 0;
  if (e > 1) e = 1;
  double rate = (e >= s[0] ? u->act1 * e + u->act2 : u->act2) / u->time_scale;
  s[0] = e + (s[0] - e) * exp(-rate * h);
  // the length at the step's end: the kinematics are the step's start, the velocity its end's
  int t = u->tendon, adr = m->ten_J_rowadr[t];
  double rate_L = 0;
  for (int k = 0; k < m->ten_J_rownnz[t]; k++) rate_L += d->ten_J[adr + k] * d->qvel[m->ten_J_colind[adr + k]];
  double L = d->ten_length[t] + h * rate_L;
  s[1] = step_fibre(u, s[0], s[1], L, h);
}

mjPLUGIN_LIB_INIT(o2m_schutte) {
  mjpPlugin p;
  mjp_defaultPlugin(&p);
  p.name = "o2m.schutte";
  p.capabilityflags = mjPLUGIN_ACTUATOR;
  p.nattribute = sizeof(ATTRS) / sizeof(ATTRS[0]);
  p.attributes = ATTRS;
  p.nstate = nstate;
  p.init = init;
  p.destroy = destroy;
  p.reset = reset;
  p.compute = compute;
  p.advance = advance;
  mjp_registerPlugin(&p);
}
