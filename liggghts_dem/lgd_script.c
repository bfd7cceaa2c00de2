/* lgd_script.c — a dem_model (dem_server's scene) as LIGGGHTS 3.8 input:
 * the commands, a data file with the grains and one ASCII STL file per mesh.
 * The contact law is LIGGGHTS' `hertz tangential history`, which dem_server
 * reproduces (dem_server/README.md); the per-pair constants come from the
 * model's pair table (dem_model.law), so both codes read the same numbers. */
#include "liggghts_dem/lgd_internal.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int any_fixed_rotation(const dem_model *m) {
  for (int i = 0; i < m->n_grains; i++)
    if (m->fix_rotation[i]) return 1;
  return 0;
}

int lgd_n_types(const dem_model *m) { return m->n_materials * (any_fixed_rotation(m) ? 2 : 1); }

static int material_of_type(const dem_model *m, int type) { return (type - 1) % m->n_materials; }

/* Axis of a plane normal along ±x, ±y or ±z; -1 otherwise. */
int lgd_plane_axis(const dem_plane *p) {
  for (int d = 0; d < 3; d++)
    if (fabs(p->normal[d]) == 1.0 && p->normal[(d + 1) % 3] == 0 && p->normal[(d + 2) % 3] == 0) return d;
  return -1;
}

/* e from LIGGGHTS' β = ln e / √(ln² e + π²) as the model stores it. */
static double restitution(const dem_pair_law *l) {
  return exp(l->beta * M_PI / sqrt(1.0 - l->beta * l->beta));
}

int lgd_check_model(const dem_model *m, proto_err *err) {
  for (int i = 0; i < m->n_materials; i++) {
    const dem_material *mt = &m->mat[i];
    const double g = mt->E / (2.0 * (1.0 + mt->nu));
    if (fabs(mt->G - g) > 1e-12 * g)
      return proto_fail(err, "%s.materials[%d].G: LIGGGHTS takes G = E/(2(1+nu)) = %.6g Pa, got %.6g; "
                        "remove G (dem_server accepts a free G, liggghts_dem does not)",
                        m->key_path, i, g, mt->G);
  }
  for (int p = 0; p < m->n_planes; p++)
    if (lgd_plane_axis(&m->planes[p]) < 0) {
      const double *n = m->planes[p].normal;
      return proto_fail(err, "%s.walls[%d].normal: LIGGGHTS plane walls are axis-aligned (xplane, yplane, "
                        "zplane), got (%g, %g, %g); use a mesh wall", m->key_path, m->planes[p].wall,
                        n[0], n[1], n[2]);
    }
  if (m->n_grains < 1) return proto_fail(err, "%s.particles: no grains", m->key_path);
  return 0;
}

double *lgd_estar_table(const dem_model *m, int nt) {
  double *e = malloc(sizeof(double) * (size_t)(nt * nt));
  if (!e) return NULL;
  for (int a = 1; a <= nt; a++)
    for (int b = 1; b <= nt; b++)
      e[(a - 1) * nt + b - 1] = m->law[material_of_type(m, a)][material_of_type(m, b)].Estar;
  return e;
}

/* ------------------------------------------------------------------ text */

static int add(lgd_script *s, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int add(lgd_script *s, const char *fmt, ...) {
  for (;;) {
    va_list ap;
    va_start(ap, fmt);
    const size_t room = s->cap - s->len;
    const int n = vsnprintf(s->text ? s->text + s->len : NULL, s->text ? room : 0, fmt, ap);
    va_end(ap);
    if (n < 0) return -1;
    if (s->text && (size_t)n < room) {
      s->len += (size_t)n;
      return 0;
    }
    size_t cap = s->cap ? 2 * s->cap : 4096;
    while (cap < s->len + (size_t)n + 1) cap *= 2;
    char *t = realloc(s->text, cap);
    if (!t) return -1;
    s->text = t;
    s->cap = cap;
  }
}

void lgd_script_free(lgd_script *s) {
  free(s->text);
  memset(s, 0, sizeof *s);
}

/* "<keyword> peratomtypepair N v11 v12 ..." from a per-material-pair value */
static int add_pair_table(lgd_script *s, const dem_model *m, const char *id, const char *prop,
                          double (*value)(const dem_pair_law *)) {
  const int nt = lgd_n_types(m);
  int rc = add(s, "fix %s all property/global %s peratomtypepair %d", id, prop, nt);
  for (int a = 1; a <= nt && !rc; a++)
    for (int b = 1; b <= nt && !rc; b++)
      rc = add(s, " %.17g", value(&m->law[material_of_type(m, a)][material_of_type(m, b)]));
  return rc || add(s, "\n");
}

static double law_mu(const dem_pair_law *l) { return l->mu; }
static double law_mu_roll(const dem_pair_law *l) { return l->mu_roll; }

/* ----------------------------------------------------------------- files */

/* Box of everything the run starts with: grains, box walls, mesh nodes. With
 * `boundary m m m` LIGGGHTS never shrinks below it and grows it as needed. */
static void start_box(const dem_model *m, double lo[3], double hi[3]) {
  for (int d = 0; d < 3; d++) { lo[d] = DBL_MAX; hi[d] = -DBL_MAX; }
  double rmax = 0;
  for (int i = 0; i < m->n_grains; i++) {
    rmax = fmax(rmax, m->radius[i]);
    for (int d = 0; d < 3; d++) {
      lo[d] = fmin(lo[d], m->x0[3 * i + d] - m->radius[i]);
      hi[d] = fmax(hi[d], m->x0[3 * i + d] + m->radius[i]);
    }
  }
  for (int w = 0; w < m->n_walls; w++)
    if (m->walls[w].kind == DEM_WALL_BOX)
      for (int d = 0; d < 3; d++) {
        lo[d] = fmin(lo[d], m->walls[w].lo[d]);
        hi[d] = fmax(hi[d], m->walls[w].hi[d]);
      }
  for (int k = 0; k < m->n_meshes; k++)
    for (int a = 0; a < m->meshes[k].n_nodes; a++)
      for (int d = 0; d < 3; d++) {
        lo[d] = fmin(lo[d], m->meshes[k].x0[3 * a + d]);
        hi[d] = fmax(hi[d], m->meshes[k].x0[3 * a + d]);
      }
  for (int d = 0; d < 3; d++) { /* margin: a grain diameter and the skin */
    const double pad = 2 * rmax + m->skin + 1e-6 * (hi[d] - lo[d]);
    lo[d] -= pad;
    hi[d] += pad;
  }
}

static int write_data(const dem_model *m, const char *path, proto_err *err) {
  FILE *f = fopen(path, "w");
  if (!f) return proto_fail(err, "%s: cannot write the LIGGGHTS data file", path);
  double lo[3], hi[3];
  start_box(m, lo, hi);
  fprintf(f, "LIGGGHTS data file (cosim liggghts_dem)\n\n%d atoms\n%d atom types\n\n", m->n_grains,
          lgd_n_types(m));
  for (int d = 0; d < 3; d++) fprintf(f, "%.17g %.17g %clo %chi\n", lo[d], hi[d], "xyz"[d], "xyz"[d]);
  fprintf(f, "\nAtoms\n\n");
  for (int i = 0; i < m->n_grains; i++) {
    const double *x = &m->x0[3 * i];
    fprintf(f, "%d %d %.17g %.17g %.17g %.17g %.17g\n", i + 1, lgd_type(m, m->material[i], m->fix_rotation[i]),
            2 * m->radius[i], m->mat[m->material[i]].density, x[0], x[1], x[2]);
  }
  fprintf(f, "\nVelocities\n\n");
  for (int i = 0; i < m->n_grains; i++) {
    const double *v = &m->v0[3 * i], *w = &m->omega0[3 * i];
    const int fixed = m->fix_rotation[i]; /* dem_server: a grain that does not rotate has ω = 0 */
    fprintf(f, "%d %.17g %.17g %.17g %.17g %.17g %.17g\n", i + 1, v[0], v[1], v[2], fixed ? 0 : w[0],
            fixed ? 0 : w[1], fixed ? 0 : w[2]);
  }
  return fclose(f) == 0 ? 0 : proto_fail(err, "%s: write failed", path);
}

/* ASCII STL, the triangles in model order: LIGGGHTS numbers them by file
 * order (0-based), which the shim relies on, and reads vertices with full
 * double precision (atof). (The 3.8 legacy-VTK reader miscounts the header
 * lines of a standard file and cannot be used.) */
static int write_mesh(const dem_mesh *me, const double *x, const char *path, proto_err *err) {
  FILE *f = fopen(path, "w");
  if (!f) return proto_fail(err, "%s: cannot write the mesh file", path);
  fprintf(f, "solid cosim\n");
  for (int t = 0; t < me->n_tri; t++) {
    fprintf(f, "facet normal 0 0 0\nouter loop\n");
    for (int k = 0; k < 3; k++) {
      const double *p = &x[3 * me->tri[3 * t + k]];
      fprintf(f, "vertex %.17g %.17g %.17g\n", p[0], p[1], p[2]);
    }
    fprintf(f, "endloop\nendfacet\n");
  }
  fprintf(f, "endsolid cosim\n");
  return fclose(f) == 0 ? 0 : proto_fail(err, "%s: write failed", path);
}

/* -------------------------------------------------------------- commands */

/* LIGGGHTS' tolerance (`precision`, m) for a contact point just outside a
 * triangle to still count as a face contact. Between faces that LIGGGHTS
 * takes as coplanar (bent by less than θc = acos(curvature) = 0.26°) the
 * shared edge and corners are inactive, and a grain whose centre lies over
 * that band (at most r θc/2 wide) has no contact at all: it sinks until the
 * band has narrowed below its offset. A tolerance of r_max θc covers the band
 * (the projection distance is about half the tolerance for usual triangles).
 * It is also LIGGGHTS' distance below which two nodes are the same: kept
 * below a tenth of the shortest mesh edge. LIGGGHTS caps it at 1 mm; its
 * default is 1e-8 m. */
static double face_tolerance(const dem_model *m) {
  double rmax = 0, edge = 1e-3 * 10;
  for (int i = 0; i < m->n_grains; i++) rmax = fmax(rmax, m->radius[i]);
  for (int k = 0; k < m->n_meshes; k++)
    for (int s = 0; s < 3 * m->meshes[k].n_tri; s++) {
      const double *a = &m->meshes[k].x0[3 * m->meshes[k].tri[s]];
      const double *b = &m->meshes[k].x0[3 * m->meshes[k].tri[3 * (s / 3) + (s % 3 + 1) % 3]];
      edge = fmin(edge, sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                             (a[2] - b[2]) * (a[2] - b[2])));
    }
  const double p = fmin(rmax * acos(LGD_CURVATURE), 0.1 * edge);
  return p < 1e-8 ? 1e-8 : p;
}

#define LIMIT_FORCE(m) ((m)->limit_force ? " limitForce on" : "")

static int add_walls(lgd_script *s, const dem_model *m, const char *dir, const char *model,
                     double tol, const double *surface_x, proto_err *err) {
  static const char *const plane_kw[3] = {"xplane", "yplane", "zplane"};
  int rc = 0;
  for (int p = 0; p < m->n_planes && !rc; p++) {
    const dem_plane *pl = &m->planes[p];
    const int d = lgd_plane_axis(pl);
    char id[LGD_ID_LEN];
    snprintf(id, sizeof id, LGD_FIX_PLANE, p);
    rc = add(s, "fix %s all wall/gran %s primitive type %d %s %.17g store_force yes%s\n", id, model,
             lgd_type(m, pl->material, 0), plane_kw[d], pl->point[d], LIMIT_FORCE(m));
  }
  for (int k = 0; k < m->n_meshes && !rc; k++) {
    const dem_mesh *me = &m->meshes[k];
    char id[LGD_ID_LEN], path[600];
    snprintf(id, sizeof id, LGD_FIX_MESH, k);
    snprintf(path, sizeof path, "%s/mesh%d.stl", dir, k);
    if (write_mesh(me, me->coupled && surface_x ? surface_x : me->x0, path, err)) return -1;
    rc = add(s, "fix %s all mesh/surface/stress file %s type %d precision %.6g curvature_tolerant yes\n", id, path,
             lgd_type(m, me->material, 0), tol);
    const double *u = me->velocity;
    if (!rc && !me->coupled && (u[0] != 0 || u[1] != 0 || u[2] != 0))
      rc = add(s, "fix %s_move all move/mesh mesh %s linear %.17g %.17g %.17g\n", id, id, u[0], u[1], u[2]);
  }
  if (m->n_meshes > 0 && !rc) {
    rc = add(s, "fix %s all wall/gran %s mesh n_meshes %d meshes", LGD_FIX_MESHWALL, model, m->n_meshes);
    for (int k = 0; k < m->n_meshes && !rc; k++) rc = add(s, " " LGD_FIX_MESH, k);
    if (!rc) rc = add(s, " store_force_contact_stress yes%s\n", LIMIT_FORCE(m));
  }
  return rc ? proto_fail(err, "LIGGGHTS input: out of memory") : 0;
}

int lgd_script_build(const dem_model *m, const char *dir, double tol, double dt, const char *restart,
                     const double *surface_x, lgd_script *s, proto_err *err) {
  memset(s, 0, sizeof *s);
  if (lgd_check_model(m, err)) return -1;
  char data[600];
  snprintf(data, sizeof data, "%s/grains.data", dir);
  if (!restart && write_data(m, data, err)) return -1;
  const int nt = lgd_n_types(m);
  /* granular pair style and walls need `newton off` and ghost velocities
   * (docs/liggghts.md §3); the soft/hard switches lift LIGGGHTS'
   * sanity limits on Young's modulus (5e6 ≤ E ≤ 1e9 Pa in SI) */
  int rc = add(s, "units si\natom_style granular\natom_modify map array\nboundary m m m\n"
                  "newton off\ncommunicate single vel yes\nprocessors * * 1\n"
                  "soft_particles yes\nhard_particles yes\n%s %s\n"
                  "neighbor %.17g bin\nneigh_modify delay 0\n", restart ? "read_restart" : "read_data",
                  restart ? restart : data, m->skin);
  rc = rc || add(s, "fix lgd_E all property/global youngsModulus peratomtype");
  for (int t = 1; t <= nt && !rc; t++) rc = add(s, " %.17g", m->mat[material_of_type(m, t)].E);
  rc = rc || add(s, "\nfix lgd_nu all property/global poissonsRatio peratomtype");
  for (int t = 1; t <= nt && !rc; t++) rc = add(s, " %.17g", m->mat[material_of_type(m, t)].nu);
  rc = rc || add(s, "\n");
  rc = rc || add_pair_table(s, m, "lgd_e", "coefficientRestitution", restitution);
  rc = rc || add_pair_table(s, m, "lgd_mu", "coefficientFriction", law_mu);
  if (m->has_rolling) rc = rc || add_pair_table(s, m, "lgd_mur", "coefficientRollingFriction", law_mu_roll);
  char model[96];
  snprintf(model, sizeof model, "model hertz tangential history%s", m->has_rolling ? " rolling_friction cdt" : "");
  /* limit_force: LIGGGHTS' `limitForce on` (F_n never attractive), after the
   * pair style's model and last in each wall fix (LIGGGHTS' keyword order) */
  rc = rc || add(s, "pair_style gran %s%s\npair_coeff * *\ntimestep %.17g\n", model, LIMIT_FORCE(m), dt);
  const double *g = m->gravity, gm = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
  if (gm > 0) rc = rc || add(s, "fix lgd_gravity all gravity %.17g vector %.17g %.17g %.17g\n", gm, g[0], g[1], g[2]);
  if (rc) return proto_fail(err, "LIGGGHTS input: out of memory");
  if (add_walls(s, m, dir, model, tol > 0 ? tol : face_tolerance(m), surface_x, err)) return -1;
  if (nt > m->n_materials) /* grains that do not rotate: translation only */
    rc = add(s, "group lgd_rot type 1:%d\ngroup lgd_fixed type %d:%d\nfix lgd_nve lgd_rot nve/sphere\n"
                "fix lgd_nve_fixed lgd_fixed nve\n", m->n_materials, m->n_materials + 1, nt);
  else
    rc = add(s, "fix lgd_nve all nve/sphere\n");
  rc = rc || add(s, "thermo_style custom step\nthermo_modify norm no\n");
  return rc ? proto_fail(err, "LIGGGHTS input: out of memory") : 0;
}
