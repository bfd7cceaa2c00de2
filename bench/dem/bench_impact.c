/* bench_impact — the one-grain impact of impact.liggghts with cosim's DEM:
 * prints per step: step z vz fz vx wy fx (the same columns as the LIGGGHTS log).
 * usage: bench_impact DT VT NSTEPS [E] [RESTITUTION] */
#include "dem_server/dem.h"

#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv) {
  if (argc < 4) { fprintf(stderr, "usage: %s DT VT NSTEPS [E]\n", argv[0]); return 2; }
  const double dt = atof(argv[1]), vt = atof(argv[2]);
  const long n = atol(argv[3]);
  const double E = argc > 4 ? atof(argv[4]) : 5e6, e = argc > 5 ? atof(argv[5]) : 0.5;
  char json[1024];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":%g,\"nu\":0.3,\"restitution\":%.17g,\"friction\":0.6}],"
           "\"gravity\":[0,0,0],\"dt\":%.17g,\"overlap_tolerance\":0.5,\"unsafe_dt\":true,"
           "\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1]}],"
           "\"particles\":[{\"x\":[0,0,0.0035001],\"v\":[%.17g,0,-0.7],\"r\":0.0035}]}", E, e, dt, vt);
  proto_err err;
  dem_model m;
  dem_state s;
  cJSON *j = cJSON_Parse(json);
  if (dem_model_from_json(&m, j, "impact", &err) || dem_state_init(&m, &s, 0, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  cJSON_Delete(j);
  printf("%ld %.15g %.15g %.15g %.15g %.15g %.15g\n", 0L, s.x[2], s.v[2], s.force[2], s.v[0], s.omega[1], s.force[0]);
  for (long k = 1; k <= n; k++) {
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
    printf("%ld %.15g %.15g %.15g %.15g %.15g %.15g\n", k, s.x[2], s.v[2], s.force[2], s.v[0], s.omega[1], s.force[0]);
  }
  dem_state_free(&s);
  dem_model_free(&m);
  return 0;
}
