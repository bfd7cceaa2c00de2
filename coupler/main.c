/* main.c — the `cosim` command line. */
#include "internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void usage(FILE *f) {
  fprintf(f,
          "usage: cosim run CONFIG [--set KEY.PATH=VALUE]... [--attach] [--quiet]\n"
          "                        [--overwrite] [--restart CHECKPOINT|latest]\n"
          "                        [--branch CHECKPOINT]\n"
          "       cosim check CONFIG [--set KEY.PATH=VALUE]...\n"
          "       cosim monitor ENDPOINT|OUTPUT_DIR [--topic PREFIX]... [--count N] [--timeout S]\n"
          "       cosim roles [--json]\n"
          "       cosim road|springs|green ARGS...   (forwarded to cosim_green)\n"
          "       cosim terra plate|shear|bed|fit|combine|curve ARGS... (forwarded to cosim_terra)\n"
          "       cosim sweep SCENE --values KEY.PATH=V1,V2,... --out DIR [--set K=V]...\n"
          "                   [--jobs N] [--repeat N] [--terra-params P.json|--reference REF.csv]\n"
          "                   (forwarded to python3 -m cosim; --help for the rest)\n"
          "       cosim watch RUN_DIR|ENDPOINT [--http 127.0.0.1:8080]   (forwarded to python3 -m cosim)\n"
          "\n"
          "run      starts the participants the scene names, couples them step by\n"
          "         step and writes results.h5 in output.dir. --attach waits for\n"
          "         participants started by hand on coupling.attach_endpoint.\n"
          "         An earlier run's results.h5 is kept: --overwrite replaces it.\n"
          "         --restart continues a run from a checkpoint (scene key\n"
          "         checkpoint.every); latest: the newest one in output.dir.\n"
          "         --branch starts a new run (its own output.dir) from a\n"
          "         checkpoint's state; the scene may change the coupling\n"
          "         scheme (coupling.scheme, coupling.implicit) besides.\n"
          "check    validates the scene (core keys here, each process section by\n"
          "         its own executable) without running it.\n"
          "monitor  prints what is published on a run's monitor bus (the endpoint,\n"
          "         or the run's output.dir, whose endpoints.json says where it is).\n"
          "sweep    one run per value of a scene key into DIR/<key>=<value>/, then\n"
          "         DIR/summary.csv (traction over the steady travel, 95 %% intervals;\n"
          "         --repeat N: N beds per value) and summary.png.\n"
          "watch    a live web page of a run (localhost; see python/README.md).\n"
          "roles    the role table: each role's messages and arrays (--json: for\n"
          "         other languages).\n"
          "Exit codes: 0 ok, 1 bad config or usage, 3 a participant failed,\n"
          "4 output error, 130 interrupted.\n");
}

typedef struct cli {
  const char *config;
  int nset;
  char **sets;
  int attach, quiet, overwrite, branch;
  const char *restart;
} cli;

static int parse(int argc, char **argv, cli *c) {
  memset(c, 0, sizeof *c);
  c->sets = calloc((size_t)argc, sizeof *c->sets);
  for (int i = 2; i < argc; i++) {
    if (strcmp(argv[i], "--set") == 0 && i + 1 < argc) {
      c->sets[c->nset++] = argv[++i];
    } else if (strncmp(argv[i], "--set=", 6) == 0) {
      c->sets[c->nset++] = argv[i] + 6;
    } else if (strcmp(argv[i], "--attach") == 0) {
      c->attach = 1;
    } else if (strcmp(argv[i], "--quiet") == 0) {
      c->quiet = 1;
    } else if (strcmp(argv[i], "--overwrite") == 0) {
      c->overwrite = 1;
    } else if ((strcmp(argv[i], "--restart") == 0 || strcmp(argv[i], "--branch") == 0) &&
               i + 1 < argc) {
      int branch = strcmp(argv[i], "--branch") == 0;
      if (c->restart) {
        fprintf(stderr, "cosim: give one of --restart and --branch, once\n");
        return -1;
      }
      c->branch = branch;
      c->restart = argv[++i];
    } else if (argv[i][0] != '-' && !c->config) {
      c->config = argv[i];
    } else {
      fprintf(stderr, "cosim: unknown option '%s'\n", argv[i]);
      return -1;
    }
  }
  if (!c->config) {
    fprintf(stderr, "cosim %s: a CONFIG file is required\n", argv[1]);
    return -1;
  }
  return 0;
}

static int cmd_check(const cli *c) {
  cpl_scene s;
  proto_err err = {{0}};
  int rc = cpl_scene_load(&s, c->config, c->nset, c->sets, &err);
  if (rc == 0) rc = cpl_check_processes(&s, &err);
  if (rc < 0) {
    fprintf(stderr, "cosim check: %s\n", err.msg);
  } else {
    printf("%s: ok — scene '%s', %lld steps of %g s, processes:", c->config,
           s.name, (long long)s.n_steps, s.dt);
    for (int i = 0; i < s.nprocs; i++)
      printf(" %s (%s)", s.procs[i].name, s.procs[i].resolved);
    printf("\n");
  }
  cpl_scene_free(&s);
  return rc < 0 ? 1 : 0;
}

static int cmd_run(const cli *c) {
  cpl_scene s;
  proto_err err = {{0}};
  if (cpl_scene_load(&s, c->config, c->nset, c->sets, &err) < 0) {
    fprintf(stderr, "cosim run: %s\n", err.msg);
    cpl_scene_free(&s);
    return 1;
  }
  cpl_run_opts opts = {.attach = c->attach, .quiet = c->quiet,
                       .progress = !c->quiet && isatty(2), .overwrite = c->overwrite,
                       .restart = c->restart, .branch = c->branch};
  int rc = cpl_run(&s, &opts);
  cpl_scene_free(&s);
  return rc;
}

/* `cosim roles [--json]`: the role table (proto/roles.c). */
static int cmd_roles(int argc, char **argv) {
  int json = argc > 2 && strcmp(argv[2], "--json") == 0;
  if (argc > 2 + json) {
    fprintf(stderr, "usage: cosim roles [--json]\n");
    return 1;
  }
  if (json) {
    cJSON *t = proto_role_table_json();
    char *text = t ? cJSON_Print(t) : NULL;
    cJSON_Delete(t);
    if (!text) return 4;
    printf("%s\n", text);
    free(text);
    return 0;
  }
  int n;
  const proto_array_spec *t = proto_role_table(&n);
  for (int r = 0; r < PROTO_N_ROLES; r++) {
    printf("role %s\n", proto_role_name((proto_role)r));
    for (int i = 0; i < n; i++) {
      if ((int)t[i].role != r) continue;
      char shape[64];
      size_t len = (size_t)snprintf(shape, sizeof shape, "[");
      for (int d = 0; d < t[i].ndim; d++) {
        const int64_t v = t[i].dims[d];
        if (v > 0)
          len += (size_t)snprintf(shape + len, sizeof shape - len, "%s%lld", d ? "," : "",
                                  (long long)v);
        else
          len += (size_t)snprintf(shape + len, sizeof shape - len, "%s%s", d ? "," : "",
                                  proto_dim_symbol(v));
      }
      snprintf(shape + len, sizeof shape - len, "]");
      printf("  %-8s %-12s %s %-6s %-6s%s%s%s%s\n    %s\n", proto_msg_type(t[i].msg),
             t[i].name, proto_dtype_name(t[i].dtype), shape, t[i].units,
             t[i].when == PROTO_WHEN_SURFACE ? " (with a surface)"
             : t[i].when == PROTO_WHEN_INDEX ? " (optional: sparse form)" : "",
             t[i].field ? " field " : "", t[i].field ? t[i].field : "",
             t[i].sum ? " (summed)" : "", t[i].meaning);
    }
  }
  return 0;
}

/* `cosim road|springs|green ...` runs the cosim_green tool next to us (with
 * the command), `cosim terra CMD ...` runs cosim_terra CMD .... */
static int forward(const char *name, char **argv) {
  char self[CPL_PATH_LEN] = {0}, tool[CPL_PATH_LEN + 16];
  ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
  char *slash = n > 0 ? strrchr(self, '/') : NULL;
  if (slash) *slash = 0;
  snprintf(tool, sizeof tool, "%s/%s", slash ? self : ".", name);
  argv[0] = tool;
  execv(tool, argv);
  fprintf(stderr, "cosim: cannot run %s (is it built?)\n", tool);
  return 1;
}

/* `cosim sweep|watch ...` runs the Python package's sweep (python/cosim/sweep_cli.py) or watch
 * with the interpreter $COSIM_PYTHON (default COSIM_PYTHON_DEFAULT), the
 * package from this source tree and this cosim binary for its runs. */
static int forward_python(char **argv) {
  char self[CPL_PATH_LEN] = {0};
  ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
  if (n > 0) setenv("COSIM_EXE", self, 0);
  const char *old = getenv("PYTHONPATH");
  char path[2 * CPL_PATH_LEN];
  snprintf(path, sizeof path, "%s%s%s", COSIM_PYTHON_DIR, old && *old ? ":" : "",
           old ? old : "");
  setenv("PYTHONPATH", path, 1);
  const char *py = getenv("COSIM_PYTHON");
  if (!py || !*py) py = COSIM_PYTHON_DEFAULT;
  /* argv[0] = "cosim", argv[1] = "sweep": becomes py -m cosim sweep ... */
  int argc = 0;
  while (argv[argc]) argc++;
  char **args = calloc((size_t)argc + 3, sizeof *args);
  if (!args) return 1;
  args[0] = (char *)py;
  args[1] = "-m";
  args[2] = "cosim";
  for (int i = 1; i < argc; i++) args[i + 2] = argv[i];
  execvp(py, args);
  fprintf(stderr, "cosim: cannot run %s for 'cosim %s' (set COSIM_PYTHON)\n", py, argv[1]);
  free(args);
  return 1;
}

int cpl_main(int argc, char **argv) {
  if (argc < 2 || strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "--help") == 0 ||
      strcmp(argv[1], "help") == 0) {
    usage(argc < 2 ? stderr : stdout);
    return argc < 2 ? 1 : 0;
  }
  const char *cmd = argv[1];
  if (strcmp(cmd, "monitor") == 0) return cpl_monitor_main(argc - 1, argv + 1);
  if (strcmp(cmd, "roles") == 0) return cmd_roles(argc, argv);
  if (strcmp(cmd, "road") == 0 || strcmp(cmd, "springs") == 0 ||
      strcmp(cmd, "green") == 0)
    return forward("cosim_green", argv);
  if (strcmp(cmd, "terra") == 0) return forward("cosim_terra", argv + 1);
  if (strcmp(cmd, "sweep") == 0 || strcmp(cmd, "watch") == 0) return forward_python(argv);
  if (strcmp(cmd, "run") != 0 && strcmp(cmd, "check") != 0) {
    fprintf(stderr, "cosim: unknown command '%s'\n", cmd);
    usage(stderr);
    return 1;
  }
  cli c;
  int rc = parse(argc, argv, &c);
  if (rc == 0) rc = strcmp(cmd, "run") == 0 ? cmd_run(&c) : cmd_check(&c);
  else rc = 1;
  free(c.sets);
  return rc;
}
