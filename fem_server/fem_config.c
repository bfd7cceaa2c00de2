/* fem_config.c — the processes.<name> section of a scene and the model it
 * describes. Every error names the key path. */
#include "fem_server/fem.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void fem_config_defaults(fem_config *c) {
  memset(c, 0, sizeof *c);
  c->source = FEM_GEN_TREAD;
  c->size[0] = 1; c->size[1] = 0.1; c->size[2] = 0.1;
  c->cells[0] = 20; c->cells[1] = 2; c->cells[2] = 2;
  c->radii[0] = 0.1; c->radii[1] = 0.2;
  c->length = 0.05;
  c->angle = 2 * M_PI;
  fem_tread_defaults(&c->tread);
  c->element = FEM_TET4;
  c->mat = (fem_material){20e6, 0.45, 1100, 0};
  c->mode = FEM_EXPLICIT;
  c->solver = FEM_CHOLMOD;
  c->safety = 0.9;
  c->power_iterations = 300;
  c->initial_static = 1;
  snprintf(c->surface_group, sizeof c->surface_group, "outer");
}

static int read_cells(proto_cfg *m, const char *key, int *cells, proto_err *err) {
  double v[3];
  int rc = proto_cfg_vec(m, key, PROTO_OPTIONAL, v, 3, 3, NULL);
  if (rc) return rc;
  if (!proto_cfg_raw(m, key, PROTO_OPTIONAL)) return 0;
  for (int d = 0; d < 3; d++) {
    if (v[d] < 1 || v[d] > 100000 || v[d] != floor(v[d]))
      return proto_fail(err, "%s.%s[%d]: must be an integer >= 1 (got %g)", m->path, key, d, v[d]);
    cells[d] = (int)v[d];
  }
  if ((double)cells[0] * cells[1] * cells[2] * 6 > FEM_MAX_ELEMS)
    return proto_fail(err, "%s.%s: %d x %d x %d cells make more than the %lld elements a mesh "
                      "may have", m->path, key, cells[0], cells[1], cells[2],
                      (long long)FEM_MAX_ELEMS);
  return 0;
}

static int read_mesh(proto_cfg *parent, fem_config *c, proto_err *err) {
  proto_cfg m;
  if (proto_cfg_child(parent, "mesh", PROTO_REQUIRED, &m)) return -1;
  static const char *const gens[] = {"bar", "slab", "cylinder", "tread", NULL};
  int has_file = proto_cfg_raw(&m, "file", PROTO_OPTIONAL) != NULL;
  int has_gen = proto_cfg_raw(&m, "generate", PROTO_OPTIONAL) != NULL;
  if (has_file == has_gen)
    return proto_fail(err, "%s: give exactly one of \"file\" (a .msh) or \"generate\" "
                      "(bar, slab, cylinder, tread)", m.path);
  if (proto_cfg_str(&m, "write", PROTO_OPTIONAL, c->mesh_write, sizeof c->mesh_write)) return -1;
  if (has_file) {
    c->source = FEM_MESH_FILE;
    if (proto_cfg_str(&m, "file", PROTO_REQUIRED, c->mesh_file, sizeof c->mesh_file)) return -1;
    return proto_cfg_end(&m);
  }
  int g;
  if (proto_cfg_enum(&m, "generate", PROTO_REQUIRED, gens, &g)) return -1;
  c->source = (fem_mesh_source)(g + 1);
  if (c->source == FEM_GEN_SLAB) {
    c->size[0] = 1; c->size[1] = 1; c->size[2] = 0.1;
    c->cells[0] = 10; c->cells[1] = 10; c->cells[2] = 2;
  }
  if (c->source == FEM_GEN_CYLINDER) {
    c->cells[0] = 4; c->cells[1] = 32; c->cells[2] = 1;
  }
  if (c->source == FEM_GEN_BAR || c->source == FEM_GEN_SLAB) {
    int n;
    if (proto_cfg_vec(&m, "size", PROTO_OPTIONAL, c->size, 3, 3, &n)) return -1;
    for (int d = 0; d < 3; d++)
      if (!(c->size[d] > 0)) return proto_fail(err, "%s.size[%d]: must be > 0", m.path, d);
    if (read_cells(&m, "cells", c->cells, err)) return -1;
    if (proto_cfg_num_below(&m, "jitter", PROTO_OPTIONAL, 0, 0.3, &c->jitter)) return -1;
  } else if (c->source == FEM_GEN_CYLINDER) {
    double deg = 360;
    if (proto_cfg_num(&m, "inner_radius", PROTO_OPTIONAL, 1e-9, 1e9, &c->radii[0]) ||
        proto_cfg_num(&m, "outer_radius", PROTO_OPTIONAL, 1e-9, 1e9, &c->radii[1]) ||
        proto_cfg_num(&m, "length", PROTO_OPTIONAL, 1e-9, 1e9, &c->length) ||
        proto_cfg_num(&m, "angle_deg", PROTO_OPTIONAL, 1e-6, 360, &deg) ||
        read_cells(&m, "cells", c->cells, err))
      return -1;
    if (!(c->radii[1] > c->radii[0]))
      return proto_fail(err, "%s.outer_radius: must exceed inner_radius (%g)", m.path, c->radii[0]);
    c->angle = deg * M_PI / 180;
  } else {
    fem_tread_params *t = &c->tread;
    int64_t lugs = t->lugs;
    double phase_deg = 0;
    if (proto_cfg_num(&m, "outer_diameter", PROTO_OPTIONAL, 1e-3, 100, &t->outer_diameter) ||
        proto_cfg_num(&m, "width", PROTO_OPTIONAL, 1e-4, 100, &t->width) ||
        proto_cfg_num(&m, "wall", PROTO_OPTIONAL, 1e-5, 100, &t->wall) ||
        proto_cfg_num(&m, "groove_depth", PROTO_OPTIONAL, 1e-5, 100, &t->groove_depth) ||
        proto_cfg_int(&m, "lugs", PROTO_OPTIONAL, 2, 10000, &lugs) ||
        proto_cfg_num(&m, "lug_fraction", PROTO_OPTIONAL, 0.01, 0.99, &t->lug_fraction) ||
        proto_cfg_num(&m, "lug_span", PROTO_OPTIONAL, 0.01, 1, &t->lug_span) ||
        proto_cfg_num(&m, "refine", PROTO_OPTIONAL, 0.1, 16, &t->refine) ||
        proto_cfg_num(&m, "phase_deg", PROTO_OPTIONAL, -360, 360, &phase_deg))
      return -1;
    t->lugs = (int)lugs;
    t->phase = phase_deg * M_PI / 180;
    if (!(t->outer_diameter / 2 > t->wall + t->groove_depth))
      return proto_fail(err, "%s.outer_diameter: radius must exceed wall + groove_depth", m.path);
  }
  return proto_cfg_end(&m);
}

static int read_fixed_one(const cJSON *node, const char *path, fem_config *c, proto_err *err) {
  proto_cfg f;
  if (c->n_fixed >= FEM_MAX_FIXED) return proto_fail(err, "%s: at most %d entries", path, FEM_MAX_FIXED);
  if (proto_cfg_open(&f, node, path, err)) return -1;
  char comps[8] = "xyz";
  if (proto_cfg_str(&f, "group", PROTO_REQUIRED, c->fixed_group[c->n_fixed], FEM_NAME_LEN) ||
      proto_cfg_str(&f, "components", PROTO_OPTIONAL, comps, sizeof comps))
    return -1;
  int mask = 0;
  for (const char *p = comps; *p; p++) {
    if (*p < 'x' || *p > 'z')
      return proto_fail(err, "%s.components: '%s' must be letters of \"xyz\"", path, comps);
    mask |= 1 << (*p - 'x');
  }
  if (!mask) return proto_fail(err, "%s.components: empty", path);
  c->fixed_mask[c->n_fixed++] = mask;
  return proto_cfg_end(&f);
}

static int read_fixed(proto_cfg *s, fem_config *c, proto_err *err) {
  const cJSON *node = proto_cfg_raw(s, "fixed", PROTO_OPTIONAL);
  char path[320];
  if (!node) return 0;
  if (cJSON_IsArray(node)) {
    int i = 0;
    for (const cJSON *e = node->child; e; e = e->next, i++) {
      proto_cfg_subpath(s, "fixed", i, path, sizeof path);
      if (read_fixed_one(e, path, c, err)) return -1;
    }
    return 0;
  }
  proto_cfg_subpath(s, "fixed", -1, path, sizeof path);
  return read_fixed_one(node, path, c, err);
}

static int read_pressure(proto_cfg *s, fem_config *c, proto_err *err) {
  const cJSON *node = proto_cfg_raw(s, "pressure", PROTO_OPTIONAL);
  if (!node) return 0;
  int n = cJSON_IsArray(node) ? cJSON_GetArraySize(node) : 1;
  if (n > FEM_MAX_PRESSURE) return proto_fail(err, "%s.pressure: at most %d entries", s->path, FEM_MAX_PRESSURE);
  for (int i = 0; i < n; i++) {
    const cJSON *e = cJSON_IsArray(node) ? cJSON_GetArrayItem(node, i) : node;
    char path[320];
    proto_cfg_subpath(s, "pressure", cJSON_IsArray(node) ? i : -1, path, sizeof path);
    proto_cfg p;
    if (proto_cfg_open(&p, e, path, err) ||
        proto_cfg_str(&p, "group", PROTO_REQUIRED, c->pressure_group[i], FEM_NAME_LEN) ||
        proto_cfg_num(&p, "value", PROTO_REQUIRED, -1e12, 1e12, &c->pressure[i]) ||
        proto_cfg_end(&p))
      return -1;
    c->n_pressure = i + 1;
  }
  return 0;
}

/* "road": {"z": m, "k_area": N/m^3, "quadrature": "nodes" | "exact"}: a flat
 * road solved in the FEM (fem_road.c). */
static int read_road(proto_cfg *s, fem_config *c, proto_err *err) {
  proto_cfg r;
  const int rc = proto_cfg_child(s, "road", PROTO_OPTIONAL, &r);
  if (rc != 0) return rc < 0 ? -1 : 0;
  c->road = 1;
  if (proto_cfg_num(&r, "z", PROTO_OPTIONAL, -1e3, 1e3, &c->road_z) ||
      proto_cfg_num(&r, "k_area", PROTO_REQUIRED, -INFINITY, INFINITY, &c->road_k_area))
    return -1;
  static const char *const quadratures[] = {"nodes", "exact", NULL};
  if (proto_cfg_enum(&r, "quadrature", PROTO_OPTIONAL, quadratures, &c->road_exact)) return -1;
  if (!(c->road_k_area > 0) || !isfinite(c->road_k_area))
    return proto_fail(err, "%s.k_area: must be a finite penalty per unit area > 0 (N/m^3), "
                      "got %g", r.path, c->road_k_area);
  return proto_cfg_end(&r);
}

int fem_config_read(const cJSON *section, const char *path, fem_config *c, proto_err *err) {
  fem_config_defaults(c);
  snprintf(c->path, sizeof c->path, "%s", path);
  proto_cfg s, m;
  char dummy[512];
  if (proto_cfg_open(&s, section, path, err)) return -1;
  if (proto_cfg_str(&s, "exec", PROTO_OPTIONAL, dummy, sizeof dummy)) return -1; /* ignored */
  if (read_mesh(&s, c, err)) return -1;
  static const char *const elems[] = {"tet4", "tet10", "tet4_anp", NULL};
  static const fem_elem_kind kinds[] = {FEM_TET4, FEM_TET10, FEM_TET4_ANP};
  int el = 0;
  if (proto_cfg_enum(&s, "element", PROTO_OPTIONAL, elems, &el)) return -1;
  c->element = kinds[el];
  if (proto_cfg_child(&s, "material", PROTO_REQUIRED, &m) < 0) return -1;
  if (proto_cfg_num(&m, "E", PROTO_REQUIRED, -INFINITY, INFINITY, &c->mat.E) ||
      proto_cfg_num(&m, "nu", PROTO_REQUIRED, -INFINITY, INFINITY, &c->mat.nu) ||
      proto_cfg_num(&m, "density", PROTO_REQUIRED, -INFINITY, INFINITY, &c->mat.density) ||
      proto_cfg_num(&m, "damping", PROTO_OPTIONAL, -INFINITY, INFINITY, &c->mat.damping) ||
      fem_material_check(&c->mat, m.path, err) || proto_cfg_end(&m))
    return -1;
  if (read_fixed(&s, c, err) || read_pressure(&s, c, err)) return -1;
  if (proto_cfg_vec(&s, "gravity", PROTO_OPTIONAL, c->gravity, 3, 3, NULL)) return -1;
  static const char *const modes[] = {"explicit", "quasi_static", NULL};
  static const char *const solvers[] = {"cholmod", "pcg", NULL};
  int mode = 0, solver = 0;
  int64_t piter = c->power_iterations, threads = 0;
  if (proto_cfg_enum(&s, "mode", PROTO_OPTIONAL, modes, &mode) ||
      proto_cfg_enum(&s, "solver", PROTO_OPTIONAL, solvers, &solver) ||
      proto_cfg_num(&s, "safety", PROTO_OPTIONAL, 0.01, 1.5, &c->safety) ||
      proto_cfg_num(&s, "dt_sub", PROTO_OPTIONAL, 0, 1e3, &c->dt_sub) ||
      proto_cfg_bool(&s, "allow_unstable", PROTO_OPTIONAL, &c->allow_unstable) ||
      proto_cfg_int(&s, "power_iterations", PROTO_OPTIONAL, 10, 100000, &piter) ||
      proto_cfg_bool(&s, "initial_static", PROTO_OPTIONAL, &c->initial_static) ||
      proto_cfg_str(&s, "surface", PROTO_OPTIONAL, c->surface_group, sizeof c->surface_group) ||
      read_road(&s, c, err) || proto_cfg_bool(&s, "reaction", PROTO_OPTIONAL, &c->reaction) ||
      proto_cfg_threads(&s, "threads", &threads))
    return -1;
  c->threads = (int)threads;
  c->mode = (fem_mode)mode;
  c->solver = (fem_solver_kind)solver;
  c->power_iterations = (int)piter;
  return proto_cfg_end(&s);
}

int fem_config_build(const fem_config *c, fem_model *md, proto_err *err) {
  fem_mesh mesh;
  int rc = 0;
  memset(md, 0, sizeof *md);
  switch (c->source) {
  case FEM_MESH_FILE: rc = fem_msh_read(c->mesh_file, &mesh, err); break;
  case FEM_GEN_BAR:
  case FEM_GEN_SLAB: rc = fem_gen_box(&mesh, c->size, c->cells, c->jitter, err); break;
  case FEM_GEN_CYLINDER:
    rc = fem_gen_cylinder(&mesh, c->radii[0], c->radii[1], c->length, c->angle, c->cells, err);
    break;
  case FEM_GEN_TREAD: rc = fem_gen_tread(&mesh, &c->tread, err); break;
  }
  if (rc) return -1;
  if (c->source != FEM_MESH_FILE && fem_mesh_group(&mesh, "outer", NULL) < 0) {
    /* boxes: every boundary face is "outer" unless fixed */
    const char *ex[FEM_MAX_FIXED];
    int n_ex = 0;
    for (int i = 0; i < c->n_fixed; i++) /* missing ones are reported below */
      if (fem_mesh_group(&mesh, c->fixed_group[i], NULL) >= 0) ex[n_ex++] = c->fixed_group[i];
    if (fem_mesh_add_boundary_group(&mesh, "outer", ex, n_ex, err)) {
      fem_mesh_free(&mesh);
      return -1;
    }
  }
  if (c->element == FEM_TET10 && mesh.nodes_per_elem == 4) {
    double radii[3] = {c->radii[0], c->radii[1], 0};
    fem_snap_fn snap = c->source == FEM_GEN_CYLINDER ? fem_snap_cylinder : NULL;
    if (c->source == FEM_GEN_TREAD) {
      radii[2] = c->tread.outer_diameter / 2;
      radii[1] = radii[2] - c->tread.groove_depth;
      radii[0] = radii[1] - c->tread.wall;
      snap = fem_snap_tread;
    }
    if (fem_mesh_to_tet10(&mesh, snap, radii, err)) {
      fem_mesh_free(&mesh);
      return -1;
    }
  }
  if (c->element != FEM_TET10 && mesh.nodes_per_elem == 10) {
    fem_mesh_free(&mesh);
    return proto_fail(err, "%s.mesh.file: %s holds tet10 elements but element is a tet4 kind",
                      c->path, c->mesh_file);
  }
  if (c->mesh_write[0] && fem_msh_write(c->mesh_write, &mesh, 0, err)) {
    fem_mesh_free(&mesh);
    return -1;
  }
  /* from here md owns the mesh; a failure frees all of it (no half model) */
  rc = fem_model_init(md, &mesh, &c->mat, err);
  if (rc == 0 && c->element == FEM_TET4_ANP) rc = fem_model_set_anp(md, err);
  for (int i = 0; rc == 0 && i < c->n_fixed; i++)
    if (fem_model_fix_group(md, c->fixed_group[i], c->fixed_mask[i], err))
      rc = proto_wrap(err, "%s.fixed[%d].group", c->path, i);
  if (rc == 0 && fem_mesh_group(&md->mesh, c->surface_group, err) < 0)
    rc = proto_wrap(err, "%s.surface", c->path);
  if (rc == 0) rc = fem_model_assemble(md, err);
  if (rc) fem_model_free(md);
  return rc;
}

int fem_config_loads(const fem_config *c, const fem_model *md, double *b, proto_err *err) {
  memset(b, 0, sizeof *b * (size_t)md->n_dof);
  for (int i = 0; i < c->n_pressure; i++)
    if (fem_load_pressure(md, c->pressure_group[i], c->pressure[i], b, err))
      return proto_wrap(err, "%s.pressure[%d].group", c->path, i);
  return 0;
}
