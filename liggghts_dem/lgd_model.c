/* lgd_model.c — the scene on every rank without the bed on every rank: rank 0
 * reads the section with dem_server's reader (dem_model_from_json) and keeps
 * the grains; the other ranks read it with one stand-in grain (materials,
 * walls, gravity, dt settings are all they need) and take from rank 0 what
 * depends on the grains. A 10^7-grain bed would otherwise sit, whole, in the
 * memory of every rank of every node. */
#include "liggghts_dem/lgd_internal.h"

#include <string.h>

/* Every rank learns whether any failed; rank 0's message if it failed. */
static int agree0(MPI_Comm comm, int rc, proto_err *err) {
  int mine = rc < 0, any = 0, rank;
  MPI_Comm_rank(comm, &rank);
  MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, comm);
  if (!any) return 0;
  int root_failed = rank == 0 ? mine : 0;
  MPI_Bcast(&root_failed, 1, MPI_INT, 0, comm);
  if (root_failed) MPI_Bcast(err->msg, (int)sizeof err->msg, MPI_CHAR, 0, comm);
  return -1;
}

int lgd_model_from_json(dem_model *m, const cJSON *section, const char *path, MPI_Comm comm,
                        proto_err *err) {
  int rank, rc;
  MPI_Comm_rank(comm, &rank);
  if (rank == 0) {
    rc = dem_model_from_json(m, section, path, err);
  } else {
    cJSON *light = cJSON_Duplicate(section, 1);
    cJSON *grain = cJSON_Parse("[{\"x\": [0, 0, 0], \"r\": 1}]");
    rc = light && grain && cJSON_ReplaceItemInObjectCaseSensitive(light, "particles", grain)
             ? dem_model_from_json(m, light, path, err)
             : proto_fail(err, "out of memory");
    if (!light || !cJSON_GetObjectItemCaseSensitive(light, "particles")) cJSON_Delete(grain);
    cJSON_Delete(light);
  }
  if (agree0(comm, rc, err)) {
    if (rc == 0) dem_model_free(m);
    return -1;
  }
  if (m->surface_couple) { /* the same section on every rank: all refuse */
    dem_model_free(m);
    return proto_fail(err, "%s.surface_couple: dem_server's only (LIGGGHTS gives each mesh "
                      "contact's force, not its moment: liggghts_dem's nodal forces are eq. 42's)",
                      path);
  }
  if (m->cfg.prep.on) { /* the same section on every rank: all refuse */
    dem_model_free(m);
    return proto_fail(err, "%s.particles.prepare: dem_server's only (liggghts_dem settles with the "
                      "scene's laws; load a bed prepared by dem_server with particles.file)", path);
  }
  /* what the grains decide: the smallest Rayleigh time (hence dt), the default
   * skin, and the settling and saving settings of a generated bed */
  MPI_Bcast(&m->rayleigh_time, 1, MPI_DOUBLE, 0, comm);
  MPI_Bcast(&m->skin, 1, MPI_DOUBLE, 0, comm);
  MPI_Bcast(&m->cfg, (int)sizeof m->cfg, MPI_BYTE, 0, comm);
  return 0;
}
