// o2m.fibre: a passive MuJoCo plugin that pulls on a tendon as OpenSim's Schutte1993 muscle does at
// zero activation (o2m.osim.fibres): its state is the fibre length (m), which lengthens to the
// equilibrium at the tendon's length and never shortens; the force (N) is the tendon's, from its
// strain. One instance per tendon; the curves come as tables in the instance's config
// (o2m.mj.fibre_plugin.with_fibres writes them). Built by o2m.mj.plugins.build.
// A negative fibre length switches the instance off (the muscle is excited in this run and pulls
// as the MuJoCo muscle and tendon spring it is). While on, the fibre's pull replaces the tendon's
// own spring and damper, which it cancels as MuJoCo computes them (mj_passive's polynomial spring
// with its dead band, linear damping), so a fit that changes them leaves a passive fibre alone.
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <mujoco/mujoco.h>

typedef struct {
  int tendon;
  double f0, l0, lts, sina0, fibre0;
  int nt, nq;            // table sizes
  double *strain_t, *tendon_t;   // tendon force (normalized) at strain
  double *len_t, *eq_t;          // equilibrium fibre length (m) at MTU length (m)
} Fibre;

static const char* ATTRS[] = {"tendon", "f0", "l0", "lts", "sina0", "fibre0", "strain", "tendonf", "length", "equilibrium"};

static int count(const char* s) { int n = 0; char* e; while (1) { strtod(s, &e); if (e == s) break; n++; s = e; } return n; }
static double* parse(const char* s, int* n) {
  *n = count(s); double* v = (double*)malloc(sizeof(double) * (*n)); char* e;
  for (int i = 0; i < *n; i++) { v[i] = strtod(s, &e); s = e; } return v;
}
static double interp(double x, const double* xs, const double* ys, int n) {
  if (x <= xs[0]) return ys[0];
  if (x >= xs[n - 1]) return ys[n - 1];
  int lo = 0, hi = n - 1;
  while (hi - lo > 1) { int mid = (lo + hi) / 2; if (xs[mid] <= x) lo = mid; else hi = mid; }
  double t = (x - xs[lo]) / (xs[hi] - xs[lo]); return ys[lo] + t * (ys[hi] - ys[lo]);
}
static double tendon_force(const Fibre* f, double L, double lf) {
  double s = f->sina0 * f->l0 / lf; if (s > 1) s = 1;
  double strain = (L - lf * sqrt(1 - s * s)) / f->lts - 1.0;
  return strain > 0 ? f->f0 * interp(strain, f->strain_t, f->tendon_t, f->nt) : 0.0;
}

// The pull (N) of tendon t's own spring and damper, as mj_passive applies them.
static double spring_force(const mjModel* m, const mjData* d, int t) {
  double L = d->ten_length[t], lo = m->tendon_lengthspring[2 * t], hi = m->tendon_lengthspring[2 * t + 1];
  double x = L > hi ? L - hi : (L < lo ? L - lo : 0.0);
  const mjtNum* p = m->tendon_stiffnesspoly + mjNPOLY * t;
  double k = m->tendon_stiffness[t], xn = x, F = 0;
  F += k * x;
  for (int i = 0; i < mjNPOLY; i++) { xn *= x; F += p[i] * xn; }
  return F + m->tendon_damping[t] * d->ten_velocity[t];
}

static int nstate(const mjModel* m, int instance) { return 1; }
static int init(const mjModel* m, mjData* d, int instance) {
  Fibre* f = (Fibre*)calloc(1, sizeof(Fibre));
  f->tendon = mj_name2id(m, mjOBJ_TENDON, mj_getPluginConfig(m, instance, "tendon"));
  if (f->tendon < 0) { free(f); return -1; }
  f->f0 = atof(mj_getPluginConfig(m, instance, "f0"));
  f->l0 = atof(mj_getPluginConfig(m, instance, "l0"));
  f->lts = atof(mj_getPluginConfig(m, instance, "lts"));
  f->sina0 = atof(mj_getPluginConfig(m, instance, "sina0"));
  f->fibre0 = atof(mj_getPluginConfig(m, instance, "fibre0"));
  int n1, n2;
  f->strain_t = parse(mj_getPluginConfig(m, instance, "strain"), &n1);
  f->tendon_t = parse(mj_getPluginConfig(m, instance, "tendonf"), &n2); f->nt = n1 < n2 ? n1 : n2;
  f->len_t = parse(mj_getPluginConfig(m, instance, "length"), &n1);
  f->eq_t = parse(mj_getPluginConfig(m, instance, "equilibrium"), &n2); f->nq = n1 < n2 ? n1 : n2;
  d->plugin_data[instance] = (uintptr_t)f;
  d->plugin_state[m->plugin_stateadr[instance]] = f->fibre0;
  return 0;
}
static void destroy(mjData* d, int instance) {
  Fibre* f = (Fibre*)d->plugin_data[instance];
  free(f->strain_t); free(f->tendon_t); free(f->len_t); free(f->eq_t); free(f);
  d->plugin_data[instance] = 0;
}
static void reset(const mjModel* m, mjtNum* state, void* data, int instance) {
  state[0] = atof(mj_getPluginConfig(m, instance, "fibre0"));
}
static void compute(const mjModel* m, mjData* d, int instance, int bit) {
  Fibre* f = (Fibre*)d->plugin_data[instance];
  mjtNum* lf = d->plugin_state + m->plugin_stateadr[instance];
  if (*lf < 0) return;  // off: an excited muscle
  int t = f->tendon;
  double L = d->ten_length[t];
  double eq = interp(L, f->len_t, f->eq_t, f->nq);
  if (eq > *lf) *lf = eq;  // the fibre lengthens to equilibrium, never shortens
  double F = tendon_force(f, L, *lf) - spring_force(m, d, t);
  if (F == 0) return;
  int adr = m->ten_J_rowadr[t];  // MuJoCo 4: the tendon Jacobian is sparse, its structure in mjModel
  for (int k = 0; k < m->ten_J_rownnz[t]; k++) d->qfrc_passive[m->ten_J_colind[adr + k]] -= F * d->ten_J[adr + k];
}

mjPLUGIN_LIB_INIT(o2m_fibre) {
  mjpPlugin p;
  mjp_defaultPlugin(&p);
  p.name = "o2m.fibre";
  p.capabilityflags = mjPLUGIN_PASSIVE;
  p.nattribute = sizeof(ATTRS) / sizeof(ATTRS[0]);
  p.attributes = ATTRS;
  p.nstate = nstate;
  p.init = init;
  p.destroy = destroy;
  p.reset = reset;
  p.compute = compute;
  mjp_registerPlugin(&p);
}
