/* ter_dem.c — virtual soil tests on dem_server's library (the bevameter of
 * Bekker 1969 and the direct shear box of ASTM D3080), through
 * its public API only (dem_server/dem.h): the model from a JSON section built
 * here from the scene's DEM section, dem_state_init, dem_settle, dem_step,
 * dem_mesh_set_nodes to move rigid meshes, wall forces.
 *
 * Rigid tools are mesh walls (two-sided triangles); each tool part is its own
 * wall so that its force is reported on its own (dem_state.wall_force, the
 * force of the grains ON the wall).
 *
 * A preparation (ter_prep) swaps the model's pair laws' friction and rolling
 * friction while the grains settle and consolidate, then puts the scene's
 * back; ter_prepare_bed runs the scene's own section that way and writes
 * the settled bed with dem_bed_save. */
#include "terra/terra.h"

#include "dem_server/dem.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TER_PARK_Z 5.0          /* tools wait here (m) while the grains settle */
#define TER_PLATE_GAP 0.1       /* plate starts this many max diameters above the highest grain */
#define TER_SKIRT_EXTRA 0.05    /* skirt height above the deepest sinkage (m) */
#define TER_SOLID_FRACTION 0.6  /* to size a shear specimen from its volume */
#define TER_BED_GAP 0.5e-3      /* clearance of the lattice placement (m) */
#define TER_SERVO_FILTER 20     /* platen force low-pass, in DEM steps */
#define TER_CONSOLIDATE_TOL 0.02   /* |N/N_target - 1| that counts as holding sigma_n */
#define TER_CONSOLIDATE_HOLD 0.02 /* s within tolerance before shearing */
#define TER_CONSOLIDATE_MAX 2.0   /* s */
#define TER_PLATEN_INSET 0.2      /* platen edge inside the box, fraction of d_min */

enum { F_BOTTOM = 1, F_XLO = 2, F_XHI = 4, F_YLO = 8, F_YHI = 16, F_SIDES = 30 };

/* ------------------------------------------------------------ the scene */

int ter_dem_soil_from_scene(const cJSON *scene, ter_dem_soil *soil, proto_err *err) {
  memset(soil, 0, sizeof *soil);
  const cJSON *procs = cJSON_GetObjectItemCaseSensitive(scene, "processes");
  if (!cJSON_IsObject(procs)) return proto_fail(err, "scene: no 'processes' object");
  for (const cJSON *p = procs->child; p; p = p->next) {
    const cJSON *ex = cJSON_GetObjectItemCaseSensitive(p, "exec");
    if (!cJSON_IsString(ex)) continue;
    const char *base = strrchr(ex->valuestring, '/');
    base = base ? base + 1 : ex->valuestring;
    if (strcmp(base, "dem_server") != 0) continue;
    soil->section = p;
    snprintf(soil->path, sizeof soil->path, "processes.%s", p->string);
  }
  if (!soil->section) return proto_fail(err, "scene: no process with exec \"dem_server\"");
  const cJSON *parts = cJSON_GetObjectItemCaseSensitive(soil->section, "particles");
  const cJSON *gm = cJSON_IsObject(parts) ? cJSON_GetObjectItemCaseSensitive(parts, "material") : NULL;
  const cJSON *walls = cJSON_GetObjectItemCaseSensitive(soil->section, "walls");
  const cJSON *w0 = cJSON_IsArray(walls) ? cJSON_GetArrayItem(walls, 0) : NULL;
  const cJSON *wm = w0 ? cJSON_GetObjectItemCaseSensitive(w0, "material") : NULL;
  const cJSON *sm = cJSON_GetObjectItemCaseSensitive(soil->section, "surface_material");
  soil->grain_material = cJSON_IsNumber(gm) ? gm->valueint : 0;
  soil->wall_material = cJSON_IsNumber(wm) ? wm->valueint : soil->grain_material;
  soil->plate_material = cJSON_IsNumber(sm) ? sm->valueint : soil->grain_material;
  return 0;
}

/* The scene's section without its grains, walls and coupled surface. */
static cJSON *base_section(const ter_dem_soil *soil, proto_err *err) {
  cJSON *s = cJSON_Duplicate(soil->section, 1);
  if (!s) {
    proto_fail(err, "out of memory");
    return NULL;
  }
  static const char *const drop[] = {"exec", "particles", "walls", "surface_material", "threads"};
  for (size_t k = 0; k < sizeof drop / sizeof *drop; k++) cJSON_DeleteItemFromObjectCaseSensitive(s, drop[k]);
  if (soil->threads > 0) cJSON_AddNumberToObject(s, "threads", soil->threads);
  cJSON_AddArrayToObject(s, "walls");
  return s;
}

static cJSON *vec3(double a, double b, double c) {
  const double v[3] = {a, b, c};
  return cJSON_CreateDoubleArray(v, 3);
}

/* A mesh wall made of the chosen faces of the box [lo, hi] (4 nodes and 2
 * triangles per face; bottom at lo[2]). */
static void add_box_mesh(cJSON *walls, int material, const double lo[3], const double hi[3],
                         unsigned faces) {
  cJSON *w = cJSON_CreateObject(), *nodes = cJSON_CreateArray(), *tris = cJSON_CreateArray();
  cJSON_AddStringToObject(w, "type", "mesh");
  cJSON_AddNumberToObject(w, "material", material);
  const double x0 = lo[0], x1 = hi[0], y0 = lo[1], y1 = hi[1], z0 = lo[2], z1 = hi[2];
  const double quad[5][4][3] = {
      {{x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0}},  /* bottom */
      {{x0, y0, z0}, {x0, y1, z0}, {x0, y1, z1}, {x0, y0, z1}},  /* x = lo */
      {{x1, y0, z0}, {x1, y1, z0}, {x1, y1, z1}, {x1, y0, z1}},  /* x = hi */
      {{x0, y0, z0}, {x1, y0, z0}, {x1, y0, z1}, {x0, y0, z1}},  /* y = lo */
      {{x0, y1, z0}, {x1, y1, z0}, {x1, y1, z1}, {x0, y1, z1}}}; /* y = hi */
  int nn = 0;
  for (int f = 0; f < 5; f++) {
    if (!(faces & (1u << f))) continue;
    for (int a = 0; a < 4; a++) cJSON_AddItemToArray(nodes, vec3(quad[f][a][0], quad[f][a][1], quad[f][a][2]));
    const int t[2][3] = {{nn, nn + 1, nn + 2}, {nn, nn + 2, nn + 3}};
    for (int k = 0; k < 2; k++) cJSON_AddItemToArray(tris, cJSON_CreateIntArray(t[k], 3));
    nn += 4;
  }
  cJSON_AddItemToObject(w, "nodes", nodes);
  cJSON_AddItemToObject(w, "triangles", tris);
  cJSON_AddItemToArray(walls, w);
}

static void add_container(cJSON *walls, int material, double Lx, double Ly) {
  cJSON *w = cJSON_CreateObject();
  cJSON_AddStringToObject(w, "type", "box");
  cJSON_AddNumberToObject(w, "material", material);
  cJSON_AddItemToObject(w, "lo", vec3(0, 0, 0));
  cJSON_AddItemToObject(w, "hi", vec3(Lx, Ly, 100));
  cJSON_AddBoolToObject(w, "open_top", 1);
  cJSON_AddItemToArray(walls, w);
}

/* Moves mesh `mesh` rigidly: from where it is now by dz, with velocity v. */
static void move_mesh(const dem_model *m, dem_state *s, int mesh, double dz, const double v[3],
                      double *xbuf, double *vbuf) {
  const int nn = m->meshes[mesh].n_nodes;
  for (int a = 0; a < nn; a++)
    for (int d = 0; d < 3; d++) {
      xbuf[3 * a + d] = s->mesh_x[mesh][3 * a + d] + (d == 2 ? dz : 0);
      vbuf[3 * a + d] = v[d];
    }
  dem_mesh_set_nodes(m, s, mesh, xbuf, vbuf);
}

static int build(cJSON *sec, const char *path, dem_model *m, dem_state *s, proto_err *err) {
  int rc = dem_model_from_json(m, sec, path, err);
  if (rc == 0 && dem_state_init(m, s, 0, err)) {
    dem_model_free(m);
    rc = -1;
  }
  return rc;
}

static void release(dem_model *m, dem_state *s) {
  dem_state_free(s);
  dem_model_free(m);
}

/* grain-steps per wall-clock second since (step k0, time t0) */
static double rate(const dem_state *s, int64_t k0, double t0) {
  return (double)s->n * (double)(s->step - k0) / fmax(proto_now() - t0, 1e-9);
}

/* dem_settle's progress on the log (a deep bed settles for minutes): a line
 * each time the whole percent of settle_max_steps grows (dem_settle reports
 * every 50 steps: that repeated each percent 3-40 times) */
typedef struct {
  FILE *log;
  int shown; /* last percent written, -1 before the first */
} settle_log;

static void settle_progress(void *ctx, double fraction, const char *what) {
  settle_log *sl = ctx;
  const int pct = (int)floor(100 * fraction);
  if (pct <= sl->shown) return;
  sl->shown = pct;
  fprintf(sl->log, "terra: %s: %d %%\n", what, pct);
  fflush(sl->log);
}

/* `placed`: grains placed at rest on the lattice start with no kinetic
 * energy: the KE test alone stopped a 9 us-step bed after 101 steps, still in
 * free fall (dem.h DEM_SETTLE_MIN_TIME); a prepared bed settled again with
 * the scene's laws starts at rest, and the KE test may end it at once: the
 * rules dem_server's beds settle by (dem_bed_settle) */
static int settle(const dem_model *m, dem_state *s, double ke, int64_t max_steps, int placed, FILE *log,
                  proto_err *err) {
  double t0 = proto_now();
  int64_t k0 = s->step;
  settle_log sl = {log, -1};
  const dem_progress_fn fn = log ? settle_progress : NULL;
  if (placed ? dem_settle_placed(m, s, ke, max_steps, fn, &sl, err) : dem_settle(m, s, ke, max_steps, fn, &sl, err))
    return -1;
  if (log)
    fprintf(log, "terra: %d grains settled in %lld steps of %.3g s (%.1f s wall, %.3g grain-steps/s), "
            "KE %.3g J per grain\n", s->n, (long long)(s->step - k0), s->dt, proto_now() - t0,
            rate(s, k0, t0), s->kinetic_energy / s->n);
  if (log && s->step - k0 >= max_steps && s->kinetic_energy >= ke * s->n)
    fprintf(log, "terra: warning: settling stopped at its %lld-step limit (%.3g s at this step) with "
            "KE %.3g J per grain above the %.3g J it settles to: the bed may still move; raise "
            "--settle-steps\n", (long long)max_steps, (double)max_steps * s->dt, s->kinetic_energy / s->n, ke);
  return 0;
}

/* --------------------------------------------------------- preparation */

/* The scene's contact laws while the preparation's are in force. */
typedef struct prep_saved {
  dem_pair_law law[DEM_MAX_MATERIALS][DEM_MAX_MATERIALS];
} prep_saved;

/* The override and its checks are dem_server's (dem.h dem_prep, one owner
 * with particles.prepare); terra's ter_prep carries the same three values. */
static dem_prep as_dem_prep(const ter_prep *p) { return (dem_prep){p->on, p->friction, p->rolling}; }

static int prep_check(const dem_model *m, const ter_prep *p, proto_err *err) {
  const dem_prep d = as_dem_prep(p);
  return dem_prep_check(m, &d, "preparation", err);
}

/* Every law's friction and rolling friction become the preparation's
 * (dem_prep_laws); the scene's laws are kept in *sv for prep_restore. At the
 * switch back the tangential springs stay as they are: the scene's Coulomb
 * rule limits them at the next step. */
static void prep_apply(dem_model *m, const ter_prep *p, prep_saved *sv) {
  memcpy(sv->law, m->law, sizeof sv->law);
  const dem_prep d = as_dem_prep(p);
  dem_prep_laws(m, &d);
}

static void prep_restore(dem_model *m, const prep_saved *sv) { memcpy(m->law, sv->law, sizeof m->law); }

/* A generated bed's particles settle as the test does: its preparation
 * (when on) and its settling limits in the section, so that a substrate
 * settles alone first with those laws (dem_bed_presettle, in the reader). */
static void put_settling(cJSON *parts, const ter_prep *p, double ke, int64_t max_steps) {
  static const char *const keys[] = {"prepare", "settle_ke_per_grain", "settle_max_steps"};
  if (p->on) {
    cJSON_DeleteItemFromObjectCaseSensitive(parts, keys[0]);
    cJSON *j = cJSON_AddObjectToObject(parts, keys[0]);
    cJSON_AddNumberToObject(j, "friction", p->friction);
    cJSON_AddNumberToObject(j, "rolling_friction", p->rolling);
  }
  if (ke > 0) {
    cJSON_DeleteItemFromObjectCaseSensitive(parts, keys[1]);
    cJSON_AddNumberToObject(parts, keys[1], ke);
  }
  if (max_steps > 0) {
    cJSON_DeleteItemFromObjectCaseSensitive(parts, keys[2]);
    cJSON_AddNumberToObject(parts, keys[2], (double)max_steps);
  }
}

static void prep_meta(ter_series *out, const ter_prep *p) {
  if (p->on)
    ter_series_meta(out, "preparation", "settled with friction %.6g, rolling friction %.6g, then the scene's laws",
                    p->friction, p->rolling);
  else
    ter_series_meta(out, "preparation", "the scene's laws throughout");
}

/* Volume of the sphere (centre zc, radius r) between the planes z0 < z1. */
static double sphere_slab(double zc, double r, double z0, double z1) {
  double a = fmax(z0 - zc, -r), b = fmin(z1 - zc, r);
  if (b <= a) return 0;
  return M_PI * (r * r * (b - a) - (b * b * b - a * a * a) / 3);
}

double ter_solid_fraction(int n, const double *x, const double *radius, const double lo[3],
                          const double hi[3]) {
  const double vol = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
  if (!(vol > 0)) return 0;
  double v = 0;
  for (int i = 0; i < n; i++) {
    const double *xi = &x[3 * i];
    if (xi[0] < lo[0] || xi[0] >= hi[0] || xi[1] < lo[1] || xi[1] >= hi[1]) continue;
    v += sphere_slab(xi[2], radius[i], lo[2], hi[2]);
  }
  return v / vol;
}

/* --------------------------------------------------------------- plate */

void ter_plate_defaults(ter_plate_spec *p) {
  memset(p, 0, sizeof *p);
  p->width = 0.165;
  p->container = 0.6;
  p->depth_factor = 4;
  p->speed = 0.02;
  p->z_max = 0.04;
  p->dz = 0.5e-3;
  p->seed = 1;
  p->settle_ke = 1e-7;
  p->settle_max_steps = 40000;
}

/* Mean top of the grains under the square footprint [c - h, c + h]^2, over
 * cells of the largest diameter; mean diameter of those top grains. */
static double surface_height(const dem_state *s, double cx, double cy, double h, double *d_top) {
  double dmax = 0;
  for (int i = 0; i < s->n; i++) dmax = fmax(dmax, 2 * s->radius[i]);
  int nc = (int)floor(2 * h / dmax);
  if (nc < 1) nc = 1;
  const double cell = 2 * h / nc;
  double top[64 * 64], dsum = 0;
  int who[64 * 64], cnt = 0;
  if (nc > 64) nc = 64;
  for (int k = 0; k < nc * nc; k++) top[k] = -INFINITY, who[k] = -1;
  for (int i = 0; i < s->n; i++) {
    const double *x = &s->x[3 * i];
    int ix = (int)floor((x[0] - (cx - h)) / cell), iy = (int)floor((x[1] - (cy - h)) / cell);
    if (ix < 0 || iy < 0 || ix >= nc || iy >= nc) continue;
    double zt = x[2] + s->radius[i];
    if (zt > top[iy * nc + ix]) top[iy * nc + ix] = zt, who[iy * nc + ix] = i;
  }
  double sum = 0;
  for (int k = 0; k < nc * nc; k++)
    if (who[k] >= 0) {
      sum += top[k];
      dsum += 2 * s->radius[who[k]];
      cnt++;
    }
  *d_top = cnt ? dsum / cnt : dmax;
  return cnt ? sum / cnt : 0;
}

/* Highest point of the grains that reach into the footprint [c - h, c + h]^2. */
static double highest_top(const dem_state *s, double cx, double cy, double h) {
  double top = -INFINITY;
  for (int i = 0; i < s->n; i++) {
    const double *x = &s->x[3 * i], r = s->radius[i];
    if (fabs(x[0] - cx) < h + r && fabs(x[1] - cy) < h + r) top = fmax(top, x[2] + r);
  }
  return top;
}

static double grain_density(const dem_model *m, int material) { return m->mat[material].density; }

/* Columns of the plate-test and shear-test series. */
enum { PL_Z, PL_P, PL_P_SKIRT, PL_INERTIAL, PL_MAX_OVERLAP, PL_KE, N_PL };
enum { SH_J, SH_TAU, SH_TAU_UPPER, SH_SIGMA, SH_SIGMA_PLATEN, SH_DILATION, SH_INERTIAL, N_SH };

int ter_plate_test(const ter_dem_soil *soil, const ter_plate_spec *sp, FILE *log, ter_series *out,
                   proto_err *err) {
  if (!(sp->width > 0 && sp->container > 2 * sp->width && sp->depth_factor > 0 && sp->speed > 0 &&
        sp->z_max > 0 && sp->dz > 0 && sp->p_max >= 0))
    return proto_fail(err, "plate test: need width > 0, container > 2 width, depth_factor, speed, "
                      "z_max, dz > 0, p_max >= 0 (got %g, %g, %g, %g, %g, %g, %g)", sp->width,
                      sp->container, sp->depth_factor, sp->speed, sp->z_max, sp->dz, sp->p_max);
  static const char *const cols[N_PL] = {
      [PL_Z] = "z", [PL_P] = "p", [PL_P_SKIRT] = "p_skirt", [PL_INERTIAL] = "inertial",
      [PL_MAX_OVERLAP] = "max_overlap", [PL_KE] = "ke_per_grain"};
  if (ter_series_init(out, N_PL, cols, err)) return -1;
  cJSON *sec = base_section(soil, err);
  if (!sec) return -1;
  const double L = sp->container, b = sp->width, h = 0.5 * b, c = 0.5 * L;
  cJSON *parts = cJSON_AddObjectToObject(sec, "particles");
  cJSON_AddStringToObject(parts, "generate", "bed");
  cJSON_AddNumberToObject(parts, "scale", sp->depth_factor * L * L); /* grains per m^2 of the paper's bed */
  cJSON_AddItemToObject(parts, "size", cJSON_CreateDoubleArray((const double[2]){L, L}, 2));
  cJSON_AddNumberToObject(parts, "material", soil->grain_material);
  cJSON_AddNumberToObject(parts, "seed", (double)sp->seed);
  /* the scene's substrate under the layers, as its bed has it (dem_bed_substrate) */
  const cJSON *sub = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(soil->section, "particles"),
                                                      "substrate");
  if (sub) cJSON_AddItemToObject(parts, "substrate", cJSON_Duplicate(sub, 1));
  put_settling(parts, &sp->prep, sp->settle_ke, sp->settle_max_steps);
  char sub_text[256] = "";
  if (sub) {
    char *t = cJSON_PrintUnformatted(sub);
    snprintf(sub_text, sizeof sub_text, "%s", t ? t : "");
    cJSON_free(t);
  }
  cJSON *walls = cJSON_GetObjectItemCaseSensitive(sec, "walls");
  add_container(walls, soil->wall_material, L, L);
  const double skirt = sp->z_max + TER_SKIRT_EXTRA;
  add_box_mesh(walls, soil->plate_material, (const double[3]){c - h, c - h, TER_PARK_Z},
               (const double[3]){c + h, c + h, TER_PARK_Z + skirt}, F_BOTTOM);
  add_box_mesh(walls, soil->plate_material, (const double[3]){c - h, c - h, TER_PARK_Z},
               (const double[3]){c + h, c + h, TER_PARK_Z + skirt}, F_SIDES);
  dem_model m;
  dem_state s;
  int rc = build(sec, soil->path, &m, &s, err);
  cJSON_Delete(sec);
  if (rc) return proto_wrap(err, "plate test");
  const int w_base = 1, w_skirt = 2, mesh_base = 0, mesh_skirt = 1;
  double xbuf[3 * 24], vbuf[3 * 24];
  prep_saved laws;
  if (prep_check(&m, &sp->prep, err)) goto fail;
  prep_apply(&m, &sp->prep, &laws);
  rc = settle(&m, &s, sp->settle_ke, sp->settle_max_steps, 1, log, err);
  prep_restore(&m, &laws);
  /* prepared: settled again with the scene's laws, as dem_server settles a
   * prepared bed and as `bed` does (from rest: until the KE test holds) */
  if (rc || (sp->prep.on && settle(&m, &s, sp->settle_ke, sp->settle_max_steps, 0, log, err))) goto fail;
  double d_top, z_surf = surface_height(&s, c, c, h, &d_top);
  const double rho = grain_density(&m, soil->grain_material);
  double dmax = 0;
  for (int i = 0; i < s.n; i++) dmax = fmax(dmax, 2 * s.radius[i]);
  /* start above every grain under the plate (the surface is a mean: some stick out) */
  const double z_start = fmax(z_surf, highest_top(&s, c, c, h)) + TER_PLATE_GAP * dmax;
  const double v[3] = {0, 0, -sp->speed};
  move_mesh(&m, &s, mesh_base, z_start - TER_PARK_Z, v, xbuf, vbuf);
  move_mesh(&m, &s, mesh_skirt, z_start - TER_PARK_Z, v, xbuf, vbuf);
  ter_series_meta(out, "test", "plate");
  ter_series_meta(out, "width_m", "%.6g", b);
  ter_series_meta(out, "container_m", "%.6g", L);
  ter_series_meta(out, "depth_factor", "%.6g", sp->depth_factor);
  if (sub_text[0]) ter_series_meta(out, "substrate", "%s", sub_text);
  if (m.cfg.substrate_steps > 0)
    ter_series_meta(out, "substrate_settled_alone", "%lld steps of its own (dem_bed_presettle)",
                    (long long)m.cfg.substrate_steps);
  ter_series_meta(out, "grains", "%d", s.n);
  ter_series_meta(out, "speed_m_s", "%.6g", sp->speed);
  ter_series_meta(out, "seed", "%llu", (unsigned long long)sp->seed);
  if (sp->p_max > 0) ter_series_meta(out, "p_max_Pa", "%.6g", sp->p_max);
  ter_series_meta(out, "surface_z_m", "%.6g", z_surf);
  ter_series_meta(out, "top_grain_diameter_m", "%.6g", d_top);
  ter_series_meta(out, "dt_s", "%.6g", s.dt);
  prep_meta(out, &sp->prep);
  {
    /* the bed under the plate's column, a max diameter clear of the surface's roughness */
    const double lo[3] = {c - h, c - h, 0}, hi[3] = {c + h, c + h, z_surf - dmax};
    const double phi = ter_solid_fraction(s.n, s.x, s.radius, lo, hi);
    ter_series_meta(out, "solid_fraction", "%.4f", phi);
    ter_series_meta(out, "bulk_density_kg_m3", "%.1f", phi * rho);
  }
  double bed_top = 0;
  for (int i = 0; i < s.n; i++) bed_top = fmax(bed_top, s.x[3 * i + 2] + s.radius[i]);
  ter_series_meta(out, "bed_max_height_m", "%.6g", bed_top);
  if (log)
    fprintf(log, "terra: plate %.3g m, surface at %.4g m (top grains %.3g mm), %d grains, dt %.3g s\n",
            b, z_surf, 1e3 * d_top, s.n, s.dt);
  /* push: bins of dz sinkage */
  double acc[5] = {0, 0, 0, 0, 0}, t0 = proto_now();
  int nacc = 0, bin = 0;
  const int64_t k0 = s.step;
  while (1) {
    if (dem_step(&m, &s, err)) goto fail;
    const double sink = z_surf - s.mesh_x[mesh_base][2];
    acc[0] += s.wall_force[3 * w_base + 2] / (b * b);
    acc[1] += s.wall_force[3 * w_skirt + 2] / (b * b);
    acc[2] = fmax(acc[2], s.max_overlap_ratio);
    acc[3] += s.kinetic_energy / s.n;
    nacc++;
    if (sink >= (bin + 1) * sp->dz || sink >= sp->z_max) {
      double p = acc[0] / nacc;
      double I = p > 0 ? (sp->speed / b) * d_top / sqrt(p / rho) : INFINITY;
      const double row[N_PL] = {[PL_Z] = sink - 0.5 * sp->dz, [PL_P] = p, [PL_P_SKIRT] = acc[1] / nacc,
                                [PL_INERTIAL] = I, [PL_MAX_OVERLAP] = acc[2], [PL_KE] = acc[3] / nacc};
      if (sink > 0 && ter_series_add(out, row, err)) goto fail;
      memset(acc, 0, sizeof acc);
      nacc = 0;
      bin++;
      if (log && bin % (int)fmax(1, floor(0.1 * sp->z_max / sp->dz)) == 0)
        fprintf(log, "terra: plate sinkage %.1f mm, p %.4g Pa, I %.2g, max overlap %.3g, %.3g grain-steps/s\n",
                1e3 * sink, p, I, row[PL_MAX_OVERLAP], rate(&s, k0, t0));
    }
    if (sink >= sp->z_max || (sp->p_max > 0 && bin > 0 && out->n > 0 &&
                              out->row[(size_t)(out->n - 1) * out->ncol + PL_P] > sp->p_max))
      break;
  }
  release(&m, &s);
  return 0;
fail:
  release(&m, &s);
  ter_series_free(out);
  return proto_wrap(err, "plate test (b = %g m)", sp->width);
}

/* ----------------------------------------------------------- shear box */

void ter_shear_defaults(ter_shear_spec *p) {
  memset(p, 0, sizeof *p);
  p->length = 0.2;
  p->width = 0.2;
  p->height = 0.1;
  p->d_min = 6.555e-3; /* the bed's two upper layers: 6.9 +- 0.345 and 7.8 mm */
  p->d_max = 7.8e-3;
  p->sigma_n = 10e3;
  p->speed = 0.01;
  p->j_max = 0.04;
  p->dj = 0.25e-3;
  p->servo_gain = 0;   /* 0: 30 x speed (1 % error at a dilation rate 0.3 x speed) */
  p->servo_vmax = 0;   /* 0: max(0.05, 3 x speed) */
  p->seed = 1;
  p->settle_ke = 1e-8;
  p->settle_max_steps = 40000;
}

/* Low-passed platen force and the servo's velocity (proportional law). */
typedef struct servo {
  double N_target, N_filt, alpha, gain, vmax;
} servo;

static double servo_velocity(servo *sv, double N) {
  sv->N_filt += sv->alpha * (N - sv->N_filt);
  double e = (sv->N_target - sv->N_filt) / sv->N_target; /* > 0: press harder: go down */
  double vz = -sv->gain * e;
  return vz > sv->vmax ? sv->vmax : vz < -sv->vmax ? -sv->vmax : vz;
}

/* The box's walls = meshes, in this order. */
enum { W_LOW, W_LFLANGE, W_RING, W_UFLANGE, W_PLAT };

/* One shear test in progress: the box, the DEM, the servo and the specimen. */
typedef struct shear_run {
  const ter_shear_spec *sp;
  double L, W, H, hs, d0, d1, in, ztop; /* box (m), diameters, platen inset, lattice top */
  int64_t count;                        /* grains */
  dem_model m;
  dem_state s;
  servo sv;
  double A0, rho, mass_up;              /* platen area, grain density, grains above the plane (kg) */
  double z_plat0, t_cons0;              /* specimen height after consolidation; its start time */
  double xbuf[3 * 24], vbuf[3 * 24];
} shear_run;

/* Grains for the box: diameters uniform in [d_min, d_max], enough for height H. */
static int shear_size(shear_run *r, proto_err *err) {
  const ter_shear_spec *sp = r->sp;
  r->L = sp->length;
  r->W = sp->width;
  r->H = sp->height;
  r->hs = 0.5 * r->H;
  const double d0 = r->d0 = sp->d_min, d1 = r->d1 = sp->d_max;
  const double d3 = (pow(d1, 4) - pow(d0, 4)) / (4 * fmax(d1 - d0, 1e-300)); /* E[d^3] */
  const double vgrain = M_PI / 6 * (d1 > d0 ? d3 : d0 * d0 * d0);
  r->count = (int64_t)ceil(TER_SOLID_FRACTION * r->L * r->W * r->H / vgrain);
  const double pitch = d1 + TER_BED_GAP;
  const int64_t per_level = (int64_t)floor(r->L / pitch) * (int64_t)floor(r->W / pitch);
  if (per_level < 1) return proto_fail(err, "shear test: box smaller than one grain");
  const double lattice_top = ceil((double)r->count / per_level) * pitch;
  r->ztop = fmax(lattice_top, r->H) + 2 * d1;
  r->in = TER_PLATEN_INSET * d0;
  return 0;
}

/* The DEM section: one placeholder grain (the bed replaces it) and the box.
 * Zero-thickness walls leave the upper half's overhang (x in [L, L + j])
 * without support and the lower half's top at x in [0, j] uncovered: two
 * flanges in the shear plane stand for the walls' thickness of a real box,
 * each its own wall so that its friction stays out of the plane's shear. */
static cJSON *shear_section(const ter_dem_soil *soil, const shear_run *r, proto_err *err) {
  const double L = r->L, W = r->W, hs = r->hs, in = r->in, jm = r->sp->j_max + 2 * r->d1;
  cJSON *sec = base_section(soil, err);
  if (!sec) return NULL;
  cJSON *parts = cJSON_AddArrayToObject(sec, "particles"), *g = cJSON_CreateObject();
  cJSON_AddItemToObject(g, "x", vec3(0.5 * L, 0.5 * W, 0.5 * r->H));
  cJSON_AddNumberToObject(g, "r", 0.5 * r->d0);
  cJSON_AddNumberToObject(g, "material", soil->grain_material);
  cJSON_AddItemToArray(parts, g);
  cJSON *walls = cJSON_GetObjectItemCaseSensitive(sec, "walls");
  const int wm = soil->wall_material;
  add_box_mesh(walls, wm, (const double[3]){0, 0, 0}, (const double[3]){L, W, hs}, F_BOTTOM | F_SIDES);
  add_box_mesh(walls, wm, (const double[3]){L, 0, hs}, (const double[3]){L + jm, W, hs}, F_BOTTOM);
  add_box_mesh(walls, wm, (const double[3]){0, 0, hs}, (const double[3]){L, W, r->ztop}, F_SIDES);
  add_box_mesh(walls, wm, (const double[3]){-jm, 0, hs}, (const double[3]){0, W, hs}, F_BOTTOM);
  add_box_mesh(walls, soil->grain_material, (const double[3]){in, in, TER_PARK_Z},
               (const double[3]){L - in, W - in, TER_PARK_Z + 1}, F_BOTTOM); /* platen */
  return sec;
}

/* Model and state: the section, then the bed placed in the lower box's
 * footprint (the state's dt checked against the new grains). */
static int shear_build(const ter_dem_soil *soil, shear_run *r, proto_err *err) {
  cJSON *sec = shear_section(soil, r, err);
  if (!sec) return -1;
  int rc = dem_model_from_json(&r->m, sec, soil->path, err);
  cJSON_Delete(sec);
  if (rc) return proto_wrap(err, "shear test");
  dem_bed_spec bed = {.size = {r->L, r->W}, .n_layers = 1, .material = soil->grain_material,
                      .gap = TER_BED_GAP, .seed = r->sp->seed};
  bed.layers[0] = (dem_bed_layer){.diameter = 0.5 * (r->d0 + r->d1), .spread = 0.5 * (r->d1 - r->d0),
                                  .count = r->count};
  if (dem_bed_place(&r->m, &bed, err)) {
    dem_model_free(&r->m);
    return proto_wrap(err, "shear test");
  }
  r->m.rayleigh_time = dem_model_rayleigh(&r->m);
  if (dem_state_init(&r->m, &r->s, 0, err)) {
    dem_model_free(&r->m);
    return proto_wrap(err, "shear test");
  }
  return 0;
}

static int shear_hold(shear_run *r, proto_err *err);

/* Platen down onto the settled grains, servo only, until sigma_n holds within
 * TER_CONSOLIDATE_TOL for TER_CONSOLIDATE_HOLD; then the specimen's height and
 * the mass above the shear plane. */
static int shear_consolidate(shear_run *r, proto_err *err) {
  const ter_shear_spec *sp = r->sp;
  dem_state *s = &r->s;
  servo *sv = &r->sv;
  double top = 0;
  for (int i = 0; i < s->n; i++) top = fmax(top, s->x[3 * i + 2] + s->radius[i]);
  *sv = (servo){.N_target = sp->sigma_n * r->A0, .alpha = 1.0 / TER_SERVO_FILTER,
                .gain = sp->servo_gain > 0 ? sp->servo_gain : 30 * sp->speed,
                .vmax = sp->servo_vmax > 0 ? sp->servo_vmax : fmax(0.05, 3 * sp->speed)};
  double vz0[3] = {0, 0, -sv->vmax};
  move_mesh(&r->m, s, W_PLAT, top + 0.5 * r->d1 - TER_PARK_Z, vz0, r->xbuf, r->vbuf);
  r->t_cons0 = s->t;
  return shear_hold(r, err);
}

/* The servo alone until sigma_n holds within TER_CONSOLIDATE_TOL for
 * TER_CONSOLIDATE_HOLD (at most TER_CONSOLIDATE_MAX since consolidation
 * began); then the specimen's height and the mass above the shear plane. */
static int shear_hold(shear_run *r, proto_err *err) {
  dem_state *s = &r->s;
  servo *sv = &r->sv;
  double held = 0;
  while (held < TER_CONSOLIDATE_HOLD) {
    if (dem_step(&r->m, s, err)) return -1;
    double v[3] = {0, 0, servo_velocity(sv, s->wall_force[3 * W_PLAT + 2])};
    move_mesh(&r->m, s, W_PLAT, 0, v, r->xbuf, r->vbuf);
    held = fabs(sv->N_filt / sv->N_target - 1) < TER_CONSOLIDATE_TOL ? held + s->dt : 0;
    if (s->t - r->t_cons0 > TER_CONSOLIDATE_MAX)
      return proto_fail(err, "the platen did not hold sigma_n within %g %% in %g s (at %g Pa)",
                        100 * TER_CONSOLIDATE_TOL, TER_CONSOLIDATE_MAX, sv->N_filt / r->A0);
  }
  r->z_plat0 = s->mesh_x[W_PLAT][2];
  r->mass_up = 0;
  for (int i = 0; i < s->n; i++)
    if (s->x[3 * i + 2] > r->hs) r->mass_up += 4.0 / 3 * M_PI * pow(s->radius[i], 3) * r->rho;
  return 0;
}

static void shear_meta(const shear_run *r, ter_series *out, FILE *log) {
  const ter_shear_spec *sp = r->sp;
  const dem_state *s = &r->s;
  ter_series_meta(out, "test", "shear");
  ter_series_meta(out, "sigma_n_Pa", "%.6g", sp->sigma_n);
  ter_series_meta(out, "box_m", "%.6g x %.6g x %.6g", r->L, r->W, r->H);
  ter_series_meta(out, "diameters_m", "%.6g..%.6g", r->d0, r->d1);
  ter_series_meta(out, "grains", "%d", s->n);
  ter_series_meta(out, "specimen_height_m", "%.6g", r->z_plat0);
  prep_meta(out, &sp->prep);
  /* packing before the shear: of the whole specimen (grain mass over box area x
   * height, as a laboratory weighs it: includes the looser layer at the walls)
   * and of its core (a max diameter clear of every wall and of the platen) */
  double vg = 0;
  for (int i = 0; i < s->n; i++) vg += 4.0 / 3 * M_PI * pow(s->radius[i], 3);
  const double phi_box = vg / (r->L * r->W * r->z_plat0);
  const double lo[3] = {r->d1, r->d1, r->d1}, hi[3] = {r->L - r->d1, r->W - r->d1, r->z_plat0 - r->d1};
  const double phi_core = ter_solid_fraction(s->n, s->x, s->radius, lo, hi);
  ter_series_meta(out, "solid_fraction", "%.4f", phi_box);
  ter_series_meta(out, "bulk_density_kg_m3", "%.1f", phi_box * r->rho);
  ter_series_meta(out, "solid_fraction_core", "%.4f", phi_core);
  ter_series_meta(out, "bulk_density_core_kg_m3", "%.1f", phi_core * r->rho);
  ter_series_meta(out, "speed_m_s", "%.6g", sp->speed);
  ter_series_meta(out, "seed", "%llu", (unsigned long long)sp->seed);
  ter_series_meta(out, "dt_s", "%.6g", s->dt);
  ter_series_meta(out, "servo", "v_z = -%.4g m/s x (N_target - N)/N_target, |v_z| <= %.4g m/s", r->sv.gain,
                  r->sv.vmax);
  if (log)
    fprintf(log, "terra: shear box %d grains, specimen %.4g m high, solid fraction %.4f (core %.4f), "
            "consolidated to %.4g Pa in %.3g s\n",
            s->n, r->z_plat0, phi_box, phi_core, r->sv.N_filt / r->A0, s->t - r->t_cons0);
}

/* Shear: the upper ring and the platen move along +x up to j_max; one row per
 * dj of displacement j, the means over its steps of the stresses on the
 * plane of contact area (L - j) W. */
static int shear_displace(shear_run *r, ter_series *out, FILE *log, proto_err *err) {
  const ter_shear_spec *sp = r->sp;
  dem_state *s = &r->s;
  const double x_ring0 = s->mesh_x[W_RING][0];
  const double vr[3] = {sp->speed, 0, 0};
  move_mesh(&r->m, s, W_RING, 0, vr, r->xbuf, r->vbuf);
  move_mesh(&r->m, s, W_UFLANGE, 0, vr, r->xbuf, r->vbuf);
  double acc[5] = {0, 0, 0, 0, 0}, t0 = proto_now();
  int nacc = 0, bin = 0;
  const int64_t k0 = s->step;
  while (1) {
    if (dem_step(&r->m, s, err)) return -1;
    const double *F = s->wall_force; /* force of the grains ON each wall */
    double v[3] = {sp->speed, 0, servo_velocity(&r->sv, F[3 * W_PLAT + 2])};
    move_mesh(&r->m, s, W_PLAT, 0, v, r->xbuf, r->vbuf);
    const double j = s->mesh_x[W_RING][0] - x_ring0, Ac = (r->L - j) * r->W;
    /* equilibrium of the lower grains (lower box, upper flange) and of the
     * upper grains (ring, platen, lower flange, weight) across the plane */
    acc[0] += (F[3 * W_LOW] + F[3 * W_UFLANGE]) / Ac;
    acc[1] += -(F[3 * W_RING] + F[3 * W_PLAT] + F[3 * W_LFLANGE]) / Ac;
    acc[2] += (F[3 * W_PLAT + 2] + F[3 * W_RING + 2] + F[3 * W_LFLANGE + 2] + r->mass_up * -r->m.gravity[2]) / Ac;
    acc[3] += F[3 * W_PLAT + 2] / Ac;
    acc[4] += s->mesh_x[W_PLAT][2] - r->z_plat0;
    nacc++;
    if (j >= (bin + 1) * sp->dj || j >= sp->j_max) {
      double sig = acc[2] / nacc;
      const double row[N_SH] = {[SH_J] = j - 0.5 * sp->dj, [SH_TAU] = acc[0] / nacc,
                                [SH_TAU_UPPER] = acc[1] / nacc, [SH_SIGMA] = sig,
                                [SH_SIGMA_PLATEN] = acc[3] / nacc, [SH_DILATION] = acc[4] / nacc,
                                [SH_INERTIAL] = sig > 0 ? sp->speed / (10 * sqrt(sig / r->rho)) : INFINITY};
      if (ter_series_add(out, row, err)) return -1;
      memset(acc, 0, sizeof acc);
      nacc = 0;
      bin++;
      if (log && bin % (int)fmax(1, floor(0.1 * sp->j_max / sp->dj)) == 0)
        fprintf(log, "terra: shear j %.1f mm, tau %.4g Pa, sigma %.4g Pa, dilation %.3g mm, %.3g grain-steps/s\n",
                1e3 * j, row[SH_TAU], row[SH_SIGMA], 1e3 * row[SH_DILATION], rate(s, k0, t0));
    }
    if (j >= sp->j_max) return 0;
  }
}

int ter_shear_test(const ter_dem_soil *soil, const ter_shear_spec *sp, FILE *log, ter_series *out,
                   proto_err *err) {
  if (!(sp->length > 0 && sp->width > 0 && sp->height > 0 && sp->d_min > 0 && sp->d_max >= sp->d_min &&
        sp->sigma_n > 0 && sp->speed > 0 && sp->j_max > 0 && sp->j_max < 0.5 * sp->length && sp->dj > 0))
    return proto_fail(err, "shear test: need positive sizes, d_max >= d_min, sigma_n, speed, dj > 0 "
                      "and 0 < j_max < length/2");
  if (sp->d_max > 0.2 * sp->height)
    return proto_fail(err, "shear test: box height %g m is below 5 grain diameters (%g m)", sp->height, sp->d_max);
  static const char *const cols[N_SH] = {
      [SH_J] = "j", [SH_TAU] = "tau", [SH_TAU_UPPER] = "tau_upper", [SH_SIGMA] = "sigma",
      [SH_SIGMA_PLATEN] = "sigma_platen", [SH_DILATION] = "dilation", [SH_INERTIAL] = "inertial"};
  if (ter_series_init(out, N_SH, cols, err)) return -1;
  shear_run run = {.sp = sp}, *r = &run;
  if (shear_size(r, err) || shear_build(soil, r, err)) return -1;
  r->rho = grain_density(&r->m, soil->grain_material);
  r->A0 = (r->L - 2 * r->in) * (r->W - 2 * r->in);
  prep_saved laws;
  if (prep_check(&r->m, &sp->prep, err)) goto fail;
  prep_apply(&r->m, &sp->prep, &laws);
  int rc = settle(&r->m, &r->s, sp->settle_ke, sp->settle_max_steps, 1, log, err) || shear_consolidate(r, err);
  prep_restore(&r->m, &laws);
  /* the scene's friction back: the platen holds sigma_n again before the shear */
  if (rc || (sp->prep.on && shear_hold(r, err))) goto fail;
  shear_meta(r, out, log);
  if (shear_displace(r, out, log, err)) goto fail;
  int lost = 0;
  for (int i = 0; i < r->s.n; i++) lost += r->s.x[3 * i + 2] < -r->s.radius[i];
  ter_series_meta(out, "lost_grains", "%d", lost);
  if (log && lost) fprintf(log, "terra: %d grains fell out of the box\n", lost);
  release(&r->m, &r->s);
  return 0;
fail:
  release(&r->m, &r->s);
  ter_series_free(out);
  return proto_wrap(err, "shear test (sigma_n = %g Pa)", sp->sigma_n);
}

/* ------------------------------------------------------- prepared bed */

int ter_prepare_bed(const ter_dem_soil *soil, const ter_bed_spec *sp, const char *out, FILE *log,
                    ter_bed_result *res, proto_err *err) {
  memset(res, 0, sizeof *res);
  if (!(sp->slabs >= 1 && sp->slabs <= 16 && sp->inset >= 0 && sp->settle_max_steps >= 0))
    return proto_fail(err, "bed: need 1 <= slabs <= 16 (got %d), inset >= 0 (got %g), settle steps >= 0",
                      sp->slabs, sp->inset);
  const cJSON *parts = cJSON_GetObjectItemCaseSensitive(soil->section, "particles");
  const cJSON *gen = cJSON_IsObject(parts) ? cJSON_GetObjectItemCaseSensitive(parts, "generate") : NULL;
  if (!cJSON_IsString(gen))
    return proto_fail(err, "bed: %s.particles must be a generated bed ({\"generate\": \"bed\", ...}; "
                      "give one with --particles)", soil->path);
  cJSON *sec = cJSON_Duplicate(soil->section, 1);
  if (!sec) return proto_fail(err, "out of memory");
  static const char *const drop[] = {"exec", "threads"};
  for (size_t k = 0; k < sizeof drop / sizeof *drop; k++) cJSON_DeleteItemFromObjectCaseSensitive(sec, drop[k]);
  if (soil->threads > 0) cJSON_AddNumberToObject(sec, "threads", soil->threads);
  cJSON *p = cJSON_GetObjectItemCaseSensitive(sec, "particles");
  cJSON_DeleteItemFromObjectCaseSensitive(p, "save"); /* written here, after the second settling */
  if (sp->seed > 0) {
    cJSON_DeleteItemFromObjectCaseSensitive(p, "seed");
    cJSON_AddNumberToObject(p, "seed", (double)sp->seed);
  }
  put_settling(p, &sp->prep, 0, sp->settle_max_steps);
  dem_model m;
  dem_state s;
  int rc = build(sec, soil->path, &m, &s, err);
  cJSON_Delete(sec);
  if (rc) return proto_wrap(err, "bed");
  const int64_t steps = sp->settle_max_steps > 0 ? sp->settle_max_steps : (int64_t)m.cfg.settle_steps;
  const double ke = m.cfg.settle_ke;
  /* --prep-friction, else the section's own particles.prepare */
  const ter_prep prep = sp->prep.on || !m.cfg.prep.on
                            ? sp->prep
                            : (ter_prep){1, m.cfg.prep.friction, m.cfg.prep.rolling};
  prep_saved laws;
  if (prep_check(&m, &prep, err)) goto fail;
  prep_apply(&m, &prep, &laws);
  rc = settle(&m, &s, ke, steps, 1, log, err);
  prep_restore(&m, &laws);
  /* the scene's laws, from rest (as dem_server's dem_bed_settle) */
  if (rc || (prep.on && settle(&m, &s, ke, steps, 0, log, err))) goto fail;
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (int i = 0; i < s.n; i++)
    for (int d = 0; d < 2; d++) {
      lo[d] = fmin(lo[d], s.x[3 * i + d] - s.radius[i]);
      hi[d] = fmax(hi[d], s.x[3 * i + d] + s.radius[i]);
    }
  for (int d = 0; d < 2; d++) lo[d] += sp->inset, hi[d] -= sp->inset;
  int count = 0;
  if (!(hi[0] > lo[0] && hi[1] > lo[1])) {
    proto_fail(err, "inset %g m leaves no footprint", sp->inset);
    goto fail;
  }
  if (dem_bed_top(&s, lo, hi, 50.0, &res->top, &count, err) || count == 0) {
    if (!count) proto_fail(err, "no grain inside the inset footprint");
    goto fail;
  }
  const double rho = grain_density(&m, soil->grain_material);
  for (int k = 0; k < sp->slabs; k++) {
    const double b0[3] = {lo[0], lo[1], res->top * k / sp->slabs};
    const double b1[3] = {hi[0], hi[1], res->top * (k + 1) / sp->slabs};
    res->solid_fraction[k] = ter_solid_fraction(s.n, s.x, s.radius, b0, b1);
    res->bulk_density[k] = res->solid_fraction[k] * rho;
  }
  res->grains = s.n;
  res->max_overlap = s.max_overlap_ratio;
  if (dem_bed_save(&m, &s, out, err)) goto fail;
  if (log) {
    fprintf(log, "terra: bed of %d grains saved to %s: median top %.4g m; solid fraction (bulk density kg/m^3) "
            "by slab from the floor:", s.n, out, res->top);
    for (int k = 0; k < sp->slabs; k++) fprintf(log, " %.4f (%.0f)", res->solid_fraction[k], res->bulk_density[k]);
    fprintf(log, "\n");
  }
  release(&m, &s);
  return 0;
fail:
  release(&m, &s);
  return proto_wrap(err, "bed");
}
