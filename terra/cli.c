/* cli.c — `cosim_terra` (also `cosim terra`): the virtual soil tests, the
 * fits, and the terramechanics reference curve (terra/README.md). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "terra/terra.h"

#define MAX_FILES 16
#define MAX_SLIPS 1001

static const char USAGE[] =
    "usage: cosim_terra plate SCENE.json --width B --out FILE.csv [--container L] [--depth-factor F]\n"
    "                   [--speed V] [--zmax Z] [--dz DZ] [--seed S] [--threads T] [--settle-steps N]\n"
    "       cosim_terra shear SCENE.json --sigma P --out FILE.csv [--length L] [--box-width W]\n"
    "                   [--height H] [--dmin D] [--dmax D] [--speed V] [--jmax J] [--dj DJ]\n"
    "                   [--seed S] [--threads T] [--settle-steps N]\n"
    "       (plate and shear also take [--prep-friction MU [--prep-rolling MUR]]; plate [--pmax P])\n"
    "       cosim_terra bed SCENE.json --out BED.h5 [--particles JSON] [--prep-friction MU\n"
    "                   [--prep-rolling MUR]] [--seed S] [--settle-steps N] [--threads T]\n"
    "                   [--inset M] [--slabs K]\n"
    "       cosim_terra fit --plate FILE.csv... --shear FILE.csv... --out SOIL.json\n"
    "                   [--zmin Z] [--zmax Z] [--jfit J] [--c1 C] [--c2 C]\n"
    "       cosim_terra combine SOIL.json... --out PARAMS.json\n"
    "       cosim_terra curve --params PARAMS.json --radius R --width B --load W --out REF.csv\n"
    "                   [--slips FROM:TO:STEP]\n";

/* ------------------------------------------------------------ options */

typedef enum { OPT_NUM, OPT_STR, OPT_LIST } opt_kind;
typedef struct opt {
  const char *name;
  opt_kind kind;
  void *dst;   /* double*, const char**, or list */
  int *count;  /* OPT_LIST */
} opt;

static int parse(int argc, char **argv, int first, const opt *opts, int nopt, const char **positional,
                 proto_err *err) {
  for (int i = first; i < argc; i++) {
    const char *a = argv[i];
    if (strncmp(a, "--", 2) != 0) {
      if (positional && !*positional) {
        *positional = a;
        continue;
      }
      return proto_fail(err, "unexpected argument '%s'", a);
    }
    int k;
    for (k = 0; k < nopt; k++)
      if (strcmp(a + 2, opts[k].name) == 0) break;
    if (k == nopt) return proto_fail(err, "unknown option '%s'", a);
    if (i + 1 >= argc) return proto_fail(err, "%s needs a value", a);
    const char *v = argv[++i];
    if (opts[k].kind == OPT_STR) {
      *(const char **)opts[k].dst = v;
    } else if (opts[k].kind == OPT_LIST) {
      const char **list = opts[k].dst;
      if (*opts[k].count >= MAX_FILES) return proto_fail(err, "%s: at most %d files", a, MAX_FILES);
      list[(*opts[k].count)++] = v;
    } else {
      char *end;
      errno = 0;
      double x = strtod(v, &end);
      if (end == v || *end || errno || !isfinite(x))
        return proto_fail(err, "%s = '%s': expected a finite number", a, v);
      *(double *)opts[k].dst = x;
    }
  }
  return 0;
}

static cJSON *load_scene(const char *path, ter_dem_soil *soil, proto_err *err) {
  if (!path) {
    proto_fail(err, "no scene file given");
    return NULL;
  }
  cJSON *scene = proto_json_load(path, err);
  if (scene && ter_dem_soil_from_scene(scene, soil, err)) {
    proto_wrap(err, "%s", path);
    cJSON_Delete(scene);
    return NULL;
  }
  return scene;
}

static int need_out(const char *out, proto_err *err) {
  return out ? 0 : proto_fail(err, "--out is required");
}

/* Runs a virtual test on the scene's soil and writes its record. */
typedef int (*test_fn)(const ter_dem_soil *soil, const void *spec, ter_series *out, proto_err *err);
static int plate_fn(const ter_dem_soil *soil, const void *spec, ter_series *out, proto_err *err) {
  return ter_plate_test(soil, spec, stderr, out, err);
}
static int shear_fn(const ter_dem_soil *soil, const void *spec, ter_series *out, proto_err *err) {
  return ter_shear_test(soil, spec, stderr, out, err);
}
static int run_test(test_fn fn, const void *spec, const char *scene_path, double threads, const char *out,
                    proto_err *err) {
  ter_dem_soil soil;
  cJSON *scene = load_scene(scene_path, &soil, err);
  if (!scene) return -1;
  soil.threads = (int)threads;
  ter_series t;
  int rc = fn(&soil, spec, &t, err);
  if (!rc) {
    ter_series_meta(&t, "scene", "%s", scene_path);
    rc = ter_series_write(&t, out, err);
    ter_series_free(&t);
  }
  cJSON_Delete(scene);
  return rc;
}

/* ------------------------------------------------------- virtual tests */

/* --prep-friction MU [--prep-rolling MUR]: the preparation (terra.h ter_prep);
 * the options' values start as NAN = not given. */
static int prep_from_opts(double friction, double rolling, ter_prep *p, proto_err *err) {
  if (isnan(friction) && !isnan(rolling))
    return proto_fail(err, "--prep-rolling %g needs --prep-friction (the preparation's sliding friction)", rolling);
  if (isnan(friction)) return 0;
  *p = (ter_prep){.on = 1, .friction = friction, .rolling = isnan(rolling) ? 0 : rolling};
  if (!(friction >= 0 && friction <= 10)) return proto_fail(err, "--prep-friction %g: must lie in [0, 10]", friction);
  if (!(p->rolling >= 0 && p->rolling <= 10)) return proto_fail(err, "--prep-rolling %g: must lie in [0, 10]", rolling);
  return 0;
}

static int cmd_plate(int argc, char **argv, proto_err *err) {
  ter_plate_spec sp;
  ter_plate_defaults(&sp);
  double seed = (double)sp.seed, threads = 0, settle = (double)sp.settle_max_steps, pf = NAN, pr = NAN;
  const char *scene_path = NULL, *out = NULL;
  const opt o[] = {{"width", OPT_NUM, &sp.width, 0},          {"container", OPT_NUM, &sp.container, 0},
                   {"depth-factor", OPT_NUM, &sp.depth_factor, 0}, {"speed", OPT_NUM, &sp.speed, 0},
                   {"zmax", OPT_NUM, &sp.z_max, 0},           {"dz", OPT_NUM, &sp.dz, 0},
                   {"seed", OPT_NUM, &seed, 0},               {"threads", OPT_NUM, &threads, 0},
                   {"settle-steps", OPT_NUM, &settle, 0},     {"out", OPT_STR, &out, 0},
                   {"prep-friction", OPT_NUM, &pf, 0},        {"prep-rolling", OPT_NUM, &pr, 0},
                   {"pmax", OPT_NUM, &sp.p_max, 0}};
  if (parse(argc, argv, 2, o, sizeof o / sizeof *o, &scene_path, err) || need_out(out, err) ||
      prep_from_opts(pf, pr, &sp.prep, err))
    return -1;
  sp.seed = (uint64_t)seed;
  sp.settle_max_steps = (int64_t)settle;
  return run_test(plate_fn, &sp, scene_path, threads, out, err);
}

static int cmd_shear(int argc, char **argv, proto_err *err) {
  ter_shear_spec sp;
  ter_shear_defaults(&sp);
  double seed = (double)sp.seed, threads = 0, settle = (double)sp.settle_max_steps, pf = NAN, pr = NAN;
  const char *scene_path = NULL, *out = NULL;
  const opt o[] = {{"sigma", OPT_NUM, &sp.sigma_n, 0},   {"length", OPT_NUM, &sp.length, 0},
                   {"box-width", OPT_NUM, &sp.width, 0}, {"height", OPT_NUM, &sp.height, 0},
                   {"dmin", OPT_NUM, &sp.d_min, 0},      {"dmax", OPT_NUM, &sp.d_max, 0},
                   {"speed", OPT_NUM, &sp.speed, 0},     {"jmax", OPT_NUM, &sp.j_max, 0},
                   {"dj", OPT_NUM, &sp.dj, 0},           {"seed", OPT_NUM, &seed, 0},
                   {"threads", OPT_NUM, &threads, 0},    {"settle-steps", OPT_NUM, &settle, 0},
                   {"out", OPT_STR, &out, 0},            {"prep-friction", OPT_NUM, &pf, 0},
                   {"prep-rolling", OPT_NUM, &pr, 0}};
  if (parse(argc, argv, 2, o, sizeof o / sizeof *o, &scene_path, err) || need_out(out, err) ||
      prep_from_opts(pf, pr, &sp.prep, err))
    return -1;
  sp.seed = (uint64_t)seed;
  sp.settle_max_steps = (int64_t)settle;
  return run_test(shear_fn, &sp, scene_path, threads, out, err);
}

/* A prepared bed for the scene (terra.h ter_prepare_bed). --particles
 * replaces the scene's particles section (a JSON object), e.g. when the scene
 * itself loads the file this writes. */
static int cmd_bed(int argc, char **argv, proto_err *err) {
  ter_bed_spec sp = {.inset = 0.05, .slabs = 5};
  double seed = 0, threads = 0, settle = 0, pf = NAN, pr = NAN, slabs = sp.slabs;
  const char *scene_path = NULL, *out = NULL, *particles = NULL;
  const opt o[] = {{"out", OPT_STR, &out, 0},           {"particles", OPT_STR, &particles, 0},
                   {"prep-friction", OPT_NUM, &pf, 0},  {"prep-rolling", OPT_NUM, &pr, 0},
                   {"seed", OPT_NUM, &seed, 0},         {"settle-steps", OPT_NUM, &settle, 0},
                   {"threads", OPT_NUM, &threads, 0},   {"inset", OPT_NUM, &sp.inset, 0},
                   {"slabs", OPT_NUM, &slabs, 0}};
  if (parse(argc, argv, 2, o, sizeof o / sizeof *o, &scene_path, err) || need_out(out, err) ||
      prep_from_opts(pf, pr, &sp.prep, err))
    return -1;
  if (!(seed >= 0 && settle >= 0 && slabs >= 1 && slabs <= 16))
    return proto_fail(err, "--seed %g, --settle-steps %g must be >= 0 and --slabs %g in [1, 16]", seed, settle, slabs);
  sp.seed = (uint64_t)seed;
  sp.settle_max_steps = (int64_t)settle;
  sp.slabs = (int)slabs;
  ter_dem_soil soil;
  cJSON *scene = load_scene(scene_path, &soil, err);
  if (!scene) return -1;
  soil.threads = (int)threads;
  int rc = 0;
  if (particles) {
    cJSON *pj = proto_json_parse(particles, "--particles", err);
    if (!pj || !cJSON_IsObject(pj)) {
      cJSON_Delete(pj);
      cJSON_Delete(scene);
      return pj ? proto_fail(err, "--particles: expected a JSON object") : -1;
    }
    cJSON_ReplaceItemInObjectCaseSensitive((cJSON *)soil.section, "particles", pj);
  }
  ter_bed_result res;
  rc = ter_prepare_bed(&soil, &sp, out, stderr, &res, err);
  if (!rc) {
    printf("{\"grains\": %d, \"top_m\": %.6g, \"max_overlap\": %.4g, \"solid_fraction\": [", res.grains, res.top,
           res.max_overlap);
    for (int k = 0; k < sp.slabs; k++) printf("%s%.4f", k ? ", " : "", res.solid_fraction[k]);
    printf("], \"bulk_density_kg_m3\": [");
    for (int k = 0; k < sp.slabs; k++) printf("%s%.1f", k ? ", " : "", res.bulk_density[k]);
    printf("]}\n");
  }
  cJSON_Delete(scene);
  return rc;
}

/* ------------------------------------------------------------------ fit */

/* Plateau of a shear record: means of tau and sigma over the second half of
 * the travel; the peak of tau. */
static int shear_plateau(const ter_series *t, const char *path, double *tau_pl, double *sig_pl,
                         double *tau_peak, proto_err *err) {
  int cj = ter_series_col(t, "j"), ct = ter_series_col(t, "tau"), cs = ter_series_col(t, "sigma");
  if (cj < 0 || ct < 0 || cs < 0 || t->n < 4)
    return proto_fail(err, "%s: not a shear record (columns j, tau, sigma; >= 4 rows)", path);
  double jmax = t->row[(size_t)(t->n - 1) * t->ncol + cj], st = 0, ss = 0;
  int m = 0;
  *tau_peak = -INFINITY;
  for (int r = 0; r < t->n; r++) {
    const double *row = t->row + (size_t)r * t->ncol;
    *tau_peak = fmax(*tau_peak, row[ct]);
    if (row[cj] < 0.5 * jmax) continue;
    st += row[ct];
    ss += row[cs];
    m++;
  }
  *tau_pl = st / m;
  *sig_pl = ss / m;
  return 0;
}

/* Reads the plate records: their widths b, the largest top-grain diameter
 * *dtop and the shallowest record's end *zrec; *nread counts those to free. */
static int read_plates(int np, const char *const *plates, ter_series *P, double *b, double *dtop,
                       double *zrec, int *nread, proto_err *err) {
  for (int i = 0; i < np; i++) {
    int rc = ter_series_read(&P[i], plates[i], err);
    if (rc) return rc;
    (*nread)++;
    double d;
    rc = ter_series_meta_num(&P[i], "width_m", &b[i], err) ||
         ter_series_meta_num(&P[i], "top_grain_diameter_m", &d, err);
    if (rc) {
      proto_wrap(err, "%s", plates[i]);
      return rc;
    }
    *dtop = fmax(*dtop, d);
    int cz = ter_series_col(&P[i], "z");
    if (cz < 0 || P[i].n < 3) return proto_fail(err, "%s: not a plate record", plates[i]);
    *zrec = fmin(*zrec, P[i].row[(size_t)(P[i].n - 1) * P[i].ncol + cz]);
  }
  return 0;
}

/* One shear record: its plateau (*tau, *sig) and the Janosi–Hanamoto fit of
 * tau(j) up to jfit (<= 0: the whole record) for *K; appends its entry to js. */
static int fit_shear(const ter_series *S, const char *path, double jfit, double *tau, double *sig,
                     double *K_out, cJSON *js, proto_err *err) {
  double peak = 0, tf = 0, K = 0, rms = 0;
  int rc = shear_plateau(S, path, tau, sig, &peak, err);
  int cj = ter_series_col(S, "j"), ct = ter_series_col(S, "tau");
  double *jj = malloc(sizeof *jj * S->n), *tt = malloc(sizeof *tt * S->n);
  for (int r = 0; r < S->n && !rc; r++) {
    jj[r] = S->row[(size_t)r * S->ncol + cj];
    tt[r] = S->row[(size_t)r * S->ncol + ct];
  }
  if (!rc) rc = ter_fit_janosi(S->n, jj, tt, jfit > 0 ? jfit : INFINITY, &tf, &K, &rms, err);
  if (rc) proto_wrap(err, "%s", path);
  free(jj);
  free(tt);
  *K_out = K;
  cJSON *e = cJSON_CreateObject();
  cJSON_AddStringToObject(e, "file", path);
  cJSON_AddNumberToObject(e, "sigma", *sig);
  cJSON_AddNumberToObject(e, "tau_plateau", *tau);
  cJSON_AddNumberToObject(e, "tau_peak", peak);
  cJSON_AddNumberToObject(e, "tau_f_fit", tf);
  cJSON_AddNumberToObject(e, "K", K);
  cJSON_AddNumberToObject(e, "rms", rms);
  cJSON_AddItemToArray(js, e);
  return rc;
}

/* Mohr–Coulomb tau = c + sigma tan(phi) through the plateaus (least squares);
 * a cohesionless soil's negative intercept is curvature: refit through 0. */
static int fit_mohr_coulomb(int ns, const double *sig, const double *tau, double *c, double *tphi,
                            int *origin, proto_err *err) {
  int rc = ter_fit_line(ns, sig, tau, c, tphi, NULL, NULL, err);
  if (!rc && *c < 0) {
    double sst = 0, sss = 0;
    for (int i = 0; i < ns; i++) {
      sst += sig[i] * tau[i];
      sss += sig[i] * sig[i];
    }
    *tphi = sst / sss;
    *c = 0;
    *origin = 1;
  }
  return rc;
}

/* root.plate_fit: the range, the shared fit and each plate's own (takes jp). */
static void plate_fit_json(cJSON *root, double zmin, double zmax, const ter_plate_fit *pf, int np,
                           const char *const *plates, const double *b, cJSON *jp) {
  cJSON *pfj = cJSON_AddObjectToObject(root, "plate_fit");
  cJSON_AddNumberToObject(pfj, "z_min", zmin);
  cJSON_AddNumberToObject(pfj, "z_max", zmax);
  cJSON_AddNumberToObject(pfj, "n_shared", pf->n);
  cJSON_AddNumberToObject(pfj, "rms_log_p", pf->rms_log);
  for (int i = 0; i < np; i++) {
    cJSON *e = cJSON_CreateObject();
    cJSON_AddStringToObject(e, "file", plates[i]);
    cJSON_AddNumberToObject(e, "width", b[i]);
    cJSON_AddNumberToObject(e, "k_eq", pf->k_eq[i]);
    cJSON_AddNumberToObject(e, "n_own", pf->n_own[i]);
    cJSON_AddNumberToObject(e, "k_own", pf->k_own[i]);
    cJSON_AddNumberToObject(e, "points", pf->points[i]);
    cJSON_AddItemToArray(jp, e);
  }
  cJSON_AddItemToObject(pfj, "plates", jp);
}

static int write_json(const char *out, const cJSON *root, proto_err *err) {
  int rc = 0;
  char *text = cJSON_Print(root);
  FILE *f = fopen(out, "w");
  if (!f || fputs(text, f) < 0 || fputc('\n', f) < 0) rc = proto_fail(err, "%s: cannot write", out);
  if (f) fclose(f);
  free(text);
  return rc;
}

static int cmd_fit(int argc, char **argv, proto_err *err) {
  const char *plates[MAX_FILES], *shears[MAX_FILES], *out = NULL;
  int np = 0, ns = 0;
  ter_soil soil;
  ter_soil_defaults(&soil); /* c1, c2 unless given */
  double zmin = -1, zmax = -1, jfit = -1, c1 = soil.c1, c2 = soil.c2;
  const opt o[] = {{"plate", OPT_LIST, plates, &np}, {"shear", OPT_LIST, shears, &ns},
                   {"zmin", OPT_NUM, &zmin, 0},      {"zmax", OPT_NUM, &zmax, 0},
                   {"jfit", OPT_NUM, &jfit, 0},      {"c1", OPT_NUM, &c1, 0},
                   {"c2", OPT_NUM, &c2, 0},          {"out", OPT_STR, &out, 0}};
  if (parse(argc, argv, 2, o, sizeof o / sizeof *o, NULL, err) || need_out(out, err)) return -1;
  if (np < 2 || ns < 2) return proto_fail(err, "fit: need >= 2 --plate and >= 2 --shear records (got %d, %d)", np, ns);
  ter_series P[MAX_FILES], S[MAX_FILES];
  const ter_series *pp[MAX_FILES];
  double b[MAX_FILES], dtop = 0, zrec = INFINITY;
  int nread_p = 0, nread_s = 0;
  for (int i = 0; i < np; i++) pp[i] = &P[i];
  int rc = read_plates(np, plates, P, b, &dtop, &zrec, &nread_p, err);
  for (int i = 0; i < ns && !rc; i++) {
    rc = ter_series_read(&S[i], shears[i], err);
    if (!rc) nread_s++;
  }
  /* default range: from one top-grain diameter (the fit starts 1–2 d50 deep,
   * docs/terramechanics.md §2) to the shallowest record's end */
  if (zmin < 0) zmin = dtop;
  if (zmax < 0) zmax = zrec;
  ter_plate_fit pf;
  soil.c1 = c1;
  soil.c2 = c2;
  cJSON *root = cJSON_CreateObject(), *js = cJSON_CreateArray(), *jp = cJSON_CreateArray();
  if (!rc) rc = ter_fit_plates(np, b, pp, "z", "p", zmin, zmax, &pf, err);
  double sig[MAX_FILES], tau[MAX_FILES], Ksum = 0, Ks[MAX_FILES];
  for (int i = 0; i < ns && !rc; i++) {
    rc = fit_shear(&S[i], shears[i], jfit, &tau[i], &sig[i], &Ks[i], js, err);
    Ksum += Ks[i];
  }
  double c = 0, tphi = 0;
  int origin = 0;
  if (!rc) rc = fit_mohr_coulomb(ns, sig, tau, &c, &tphi, &origin, err);
  if (!rc) {
    soil.n = pf.n;
    soil.k_c = pf.k_c;
    soil.k_phi = pf.k_phi;
    soil.c = c;
    soil.phi = atan(tphi);
    soil.K = Ksum / ns;
    double Kvar = 0;
    for (int i = 0; i < ns; i++) Kvar += (Ks[i] - soil.K) * (Ks[i] - soil.K);
    rc = ter_soil_check(&soil, "fit", err);
    ter_soil_write(cJSON_AddObjectToObject(root, "soil"), &soil);
    plate_fit_json(root, zmin, zmax, &pf, np, plates, b, jp);
    jp = NULL;
    cJSON *mc = cJSON_AddObjectToObject(root, "mohr_coulomb");
    cJSON_AddNumberToObject(mc, "c", c);
    cJSON_AddNumberToObject(mc, "phi_deg", atan(tphi) * 180 / M_PI);
    cJSON_AddBoolToObject(mc, "through_origin", origin);
    cJSON_AddNumberToObject(mc, "K_std", ns > 1 ? sqrt(Kvar / (ns - 1)) : 0);
    cJSON_AddItemToObject(mc, "tests", js);
    js = NULL;
  }
  if (!rc) rc = write_json(out, root, err);
  cJSON_Delete(root);
  cJSON_Delete(js);
  cJSON_Delete(jp);
  for (int i = 0; i < nread_p; i++) ter_series_free(&P[i]);
  for (int i = 0; i < nread_s; i++) ter_series_free(&S[i]);
  return rc;
}

/* -------------------------------------------------------- combine, curve */

static int read_soil_file(const char *path, ter_soil *p, cJSON **root_out, proto_err *err) {
  cJSON *root = proto_json_load(path, err);
  if (!root) return -1;
  const cJSON *so = cJSON_GetObjectItemCaseSensitive(root, "soil");
  char where[600];
  snprintf(where, sizeof where, "%s: soil", path);
  int rc = so ? ter_soil_read(so, where, p, err) : proto_fail(err, "%s: no \"soil\" object", path);
  if (rc || !root_out) cJSON_Delete(root);
  else *root_out = root;
  return rc;
}

static const char *const SOIL_KEYS[] = {"n", "k_c", "k_phi", "c", "phi_deg", "K", "c1", "c2"};
#define N_SOIL_KEYS 8

static void soil_vec(const ter_soil *p, double *v) {
  const double x[N_SOIL_KEYS] = {p->n, p->k_c, p->k_phi, p->c, p->phi * 180 / M_PI, p->K, p->c1, p->c2};
  memcpy(v, x, sizeof x);
}

static int cmd_combine(int argc, char **argv, proto_err *err) {
  const char *files[MAX_FILES], *out = NULL;
  int nf = 0;
  for (int i = 2; i < argc; i++) {
    if (strcmp(argv[i], "--out") == 0 && i + 1 < argc) out = argv[++i];
    else if (strncmp(argv[i], "--", 2) == 0) return proto_fail(err, "unknown option '%s'", argv[i]);
    else if (nf < MAX_FILES) files[nf++] = argv[i];
    else return proto_fail(err, "at most %d files", MAX_FILES);
  }
  if (need_out(out, err)) return -1;
  if (nf < 2) return proto_fail(err, "combine: need >= 2 packings' SOIL.json files (got %d)", nf);
  double v[MAX_FILES][N_SOIL_KEYS], mean[N_SOIL_KEYS] = {0}, sd[N_SOIL_KEYS] = {0};
  double zr[2] = {0, INFINITY}; /* sinkage range every packing's plate fit covers */
  cJSON *root = cJSON_CreateObject(), *packs = cJSON_AddArrayToObject(root, "packings");
  for (int i = 0; i < nf; i++) {
    ter_soil p;
    cJSON *r;
    if (read_soil_file(files[i], &p, &r, err)) {
      cJSON_Delete(root);
      return -1;
    }
    const cJSON *pf = cJSON_GetObjectItemCaseSensitive(r, "plate_fit");
    const cJSON *z0 = cJSON_GetObjectItemCaseSensitive(pf, "z_min"), *z1 = cJSON_GetObjectItemCaseSensitive(pf, "z_max");
    if (cJSON_IsNumber(z0) && cJSON_IsNumber(z1)) {
      zr[0] = fmax(zr[0], z0->valuedouble);
      zr[1] = fmin(zr[1], z1->valuedouble);
    }
    cJSON *e = cJSON_Duplicate(cJSON_GetObjectItemCaseSensitive(r, "soil"), 1);
    cJSON_AddStringToObject(e, "file", files[i]);
    cJSON_AddItemToArray(packs, e);
    cJSON_Delete(r);
    soil_vec(&p, v[i]);
    for (int k = 0; k < N_SOIL_KEYS; k++) mean[k] += v[i][k] / nf;
  }
  if (isfinite(zr[1])) cJSON_AddItemToObject(root, "sinkage_fit_range", cJSON_CreateDoubleArray(zr, 2));
  cJSON *so = cJSON_AddObjectToObject(root, "soil"), *sj = cJSON_AddObjectToObject(root, "std");
  for (int k = 0; k < N_SOIL_KEYS; k++) {
    for (int i = 0; i < nf; i++) sd[k] += (v[i][k] - mean[k]) * (v[i][k] - mean[k]) / (nf - 1);
    cJSON_AddNumberToObject(so, SOIL_KEYS[k], mean[k]);
    cJSON_AddNumberToObject(sj, SOIL_KEYS[k], sqrt(sd[k]));
  }
  int rc = write_json(out, root, err);
  cJSON_Delete(root);
  return rc;
}

static int slip_range(const char *spec, double *s, int *n, proto_err *err) {
  double a, b, h;
  if (sscanf(spec, "%lf:%lf:%lf", &a, &b, &h) != 3 || !(h > 0) || !(b >= a) || a < 0 || b >= 1)
    return proto_fail(err, "--slips = '%s': expected FROM:TO:STEP with 0 <= FROM <= TO < 1, STEP > 0", spec);
  *n = 0;
  for (double x = a; x <= b + 1e-9 * h && *n < MAX_SLIPS; x += h) s[(*n)++] = x;
  return 0;
}

/* The reference: the mean parameters' curve and, with per-packing sets, the
 * band (min, max) of the curves of the packings' own parameter sets. */
static int cmd_curve(int argc, char **argv, proto_err *err) {
  const char *params = NULL, *out = NULL, *slips = "0:0.3:0.01";
  double r = 0, b = 0, W = 0;
  const opt o[] = {{"params", OPT_STR, &params, 0}, {"radius", OPT_NUM, &r, 0},
                   {"width", OPT_NUM, &b, 0},       {"load", OPT_NUM, &W, 0},
                   {"slips", OPT_STR, &slips, 0},   {"out", OPT_STR, &out, 0}};
  if (parse(argc, argv, 2, o, sizeof o / sizeof *o, NULL, err) || need_out(out, err)) return -1;
  if (!params) return proto_fail(err, "--params is required");
  if (!(r > 0 && b > 0 && W > 0)) return proto_fail(err, "--radius, --width and --load must be > 0");
  double s[MAX_SLIPS];
  int ns = 0;
  if (slip_range(slips, s, &ns, err)) return -1;
  ter_soil mean, sets[MAX_FILES];
  cJSON *root;
  if (read_soil_file(params, &mean, &root, err)) return -1;
  int nsets = 0, rc = 0;
  const cJSON *zr = cJSON_GetObjectItemCaseSensitive(root, "sinkage_fit_range");
  const int has_zr = cJSON_GetArraySize(zr) == 2;
  const double z_lo = has_zr ? cJSON_GetArrayItem(zr, 0)->valuedouble : 0;
  const double z_fit = has_zr ? cJSON_GetArrayItem(zr, 1)->valuedouble : INFINITY;
  const cJSON *packs = cJSON_GetObjectItemCaseSensitive(root, "packings");
  for (const cJSON *e = packs ? packs->child : NULL; e && !rc && nsets < MAX_FILES; e = e->next) {
    cJSON *copy = cJSON_Duplicate(e, 1);
    cJSON_DeleteItemFromObjectCaseSensitive(copy, "file");
    char where[600];
    snprintf(where, sizeof where, "%s: packings[%d]", params, nsets);
    rc = ter_soil_read(copy, where, &sets[nsets++], err);
    cJSON_Delete(copy);
  }
  cJSON_Delete(root);
  if (rc) return -1;
  /* columns: the mean soil's values, then a min/max band over the packings
   * for each of the WH_N_BANDED quantities z, F_t, R, DP, T, T/r (lo, hi) */
  enum { WH_S, WH_Z, WH_W, WH_FT, WH_R, WH_DP, WH_T, WH_T_OVER_R, WH_EFF, WH_BAND, WH_N_BANDED = 6,
         WH_N = WH_BAND + 2 * WH_N_BANDED };
  static const char *const cols[WH_N] = {"s", "z", "W", "F_t", "R", "DP", "T", "T_over_r", "eff",
                                         "z_lo", "z_hi", "F_t_lo", "F_t_hi", "R_lo", "R_hi", "DP_lo",
                                         "DP_hi", "T_lo", "T_hi", "T_over_r_lo", "T_over_r_hi"};
  ter_series t;
  if (ter_series_init(&t, WH_N, cols, err)) return -1;
  ter_series_meta(&t, "model", "rigid wheel, Bekker / Wong-Reece / Janosi-Hanamoto (terra/README.md)");
  ter_series_meta(&t, "params", "%s", params);
  ter_series_meta(&t, "radius_m", "%.6g", r);
  ter_series_meta(&t, "width_m", "%.6g", b);
  ter_series_meta(&t, "load_N", "%.6g", W);
  ter_series_meta(&t, "band", "min..max over %d packings' own parameter sets", nsets);
  ter_series_meta(&t, "columns", "F_t = r b Int tau cos (horizontal thrust); T_over_r = torque / r "
                  "(Shinone's T_H = M/R_T); DP = F_t - R");
  const ter_wheel wh = {r, b};
  int beyond = 0;
  for (int i = 0; i < ns && !rc; i++) {
    ter_forces f;
    rc = ter_solve(&wh, &mean, W, s[i], &f, err);
    double row[WH_N] = {[WH_S] = s[i], [WH_Z] = f.z, [WH_W] = f.W, [WH_FT] = f.Ft, [WH_R] = f.R,
                        [WH_DP] = f.DP, [WH_T] = f.T, [WH_T_OVER_R] = f.T / r, [WH_EFF] = f.eff};
    const double q[WH_N_BANDED] = {f.z, f.Ft, f.R, f.DP, f.T, f.T / r};
    for (int k = 0; k < WH_N_BANDED; k++) row[WH_BAND + 2 * k] = row[WH_BAND + 2 * k + 1] = q[k];
    for (int k = 0; k < nsets && !rc; k++) {
      ter_forces g;
      rc = ter_solve(&wh, &sets[k], W, s[i], &g, err);
      const double qk[WH_N_BANDED] = {g.z, g.Ft, g.R, g.DP, g.T, g.T / r};
      for (int m = 0; m < WH_N_BANDED; m++) {
        row[WH_BAND + 2 * m] = fmin(row[WH_BAND + 2 * m], qk[m]);
        row[WH_BAND + 2 * m + 1] = fmax(row[WH_BAND + 2 * m + 1], qk[m]);
      }
    }
    beyond += row[WH_BAND + 1] > z_fit; /* z_hi */
    if (!rc) rc = ter_series_add(&t, row, err);
  }
  if (isfinite(z_fit)) {
    ter_series_meta(&t, "sinkage_fit_range_m", "%.4g..%.4g", z_lo, z_fit);
    ter_series_meta(&t, "rows_beyond_fit_range", "%d", beyond);
    if (beyond)
      fprintf(stderr, "cosim_terra curve: warning: at %d of %d slips the sinkage exceeds %.4g m, the deepest "
              "the plate tests measured (extrapolated pressure-sinkage law)\n", beyond, ns, z_fit);
  }
  if (!rc) rc = ter_series_write(&t, out, err);
  ter_series_free(&t);
  return rc;
}

int main(int argc, char **argv) {
  proto_err err = {{0}};
  if (argc < 2 || strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0) {
    fputs(USAGE, argc < 2 ? stderr : stdout);
    return argc < 2 ? 1 : 0;
  }
  for (int i = 2; i < argc; i++)
    if (strcmp(argv[i], "--help") == 0) {
      fputs(USAGE, stdout);
      return 0;
    }
  const char *cmd = argv[1];
  int rc;
  if (strcmp(cmd, "plate") == 0) rc = cmd_plate(argc, argv, &err);
  else if (strcmp(cmd, "shear") == 0) rc = cmd_shear(argc, argv, &err);
  else if (strcmp(cmd, "bed") == 0) rc = cmd_bed(argc, argv, &err);
  else if (strcmp(cmd, "fit") == 0) rc = cmd_fit(argc, argv, &err);
  else if (strcmp(cmd, "combine") == 0) rc = cmd_combine(argc, argv, &err);
  else if (strcmp(cmd, "curve") == 0) rc = cmd_curve(argc, argv, &err);
  else rc = proto_fail(&err, "unknown command '%s'", cmd);
  if (rc) {
    fprintf(stderr, "cosim_terra %s: %s\n%s", cmd, err.msg, strstr(err.msg, "unknown command") ? USAGE : "");
    return 1;
  }
  return 0;
}
