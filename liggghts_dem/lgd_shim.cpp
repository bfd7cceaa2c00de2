/* lgd_shim.cpp — the little of LIGGGHTS 3.8 that its C library interface
 * cannot reach: a mesh's node positions, node velocities and edge/corner
 * activity; the per-contact forces and contact points on a mesh; the stress
 * module's total; grain–grain contact statistics from the neighbour list;
 * the per-grain sizes of a restart file. Everything else goes through
 * library.h in C.
 * Built against Debian's libliggghts-dev headers with the package's own
 * (empty) set of -D flags (docs/liggghts.md §1). */
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <unistd.h>

#include "atom.h"
#include "fix_contact_history.h"
#include "fix_contact_property_atom.h"
#include "fix_mesh_surface.h"
#include "force.h"
#include "lammps.h"
#include "modify.h"
#include "neigh_list.h"
#include "pair.h"
#include "timer.h"
#include "tri_mesh.h"

#include "liggghts_dem/lgd_internal.h"

using namespace LAMMPS_NS;

typedef MultiVectorContainer<double, 3, 3> NodeC;
typedef VectorContainer<bool, 3> FlagC;

/* Protected members reached through pointers-to-member formed in a derived
 * class (legal C++; no copy of LIGGGHTS code). */
struct TriMeshAccess : TriMesh {
  static NodeC &nodes(TriMesh *m) { return m->*(&TriMeshAccess::node_); }
  static void recalc(TriMesh *m) {
    (m->*(&TriMeshAccess::recalcLocalSurfProperties))();
    (m->*(&TriMeshAccess::recalcGhostSurfProperties))();
  }
};

static FixMeshSurface *mesh_fix(void *lmp, const char *id) {
  return dynamic_cast<FixMeshSurface *>(static_cast<LAMMPS *>(lmp)->modify->find_fix_id(id));
}

extern "C" int lgd_rows_reserve(lgd_rows *r, int more) {
  if (r->n + more <= r->cap) return 0;
  int cap = r->cap ? 2 * r->cap : 1024;
  while (cap < r->n + more) cap *= 2;
  double *v = static_cast<double *>(realloc(r->v, sizeof(double) * LGD_ROW_LEN * (size_t)cap));
  if (!v) return -1;
  r->v = v;
  r->cap = cap;
  return 0;
}

extern "C" int lgd_shim_mesh_enable_motion(void *lmp, const char *fix_id) {
  FixMeshSurface *f = mesh_fix(lmp, fix_id);
  if (!f) return -1;
  TriMesh *m = f->triMesh();
  if (!m->isMoving()) m->registerMove(false, true, false); /* elements migrate at re-neighbouring */
  if (!m->prop().getElementProperty<NodeC>("v"))
    m->prop().addElementProperty<NodeC>("v", "comm_exchange_borders", "frame_invariant", "restart_no");
  return 0;
}

extern "C" int lgd_shim_mesh_size(void *lmp, const char *fix_id) {
  FixMeshSurface *f = mesh_fix(lmp, fix_id);
  return f ? f->triMesh()->sizeGlobal() : -1;
}

extern "C" int lgd_shim_mesh_set(void *lmp, const char *fix_id, const int32_t *tri, const double *x,
                                 const double *v, const uint8_t *edge_active,
                                 const uint8_t *corner_active) {
  FixMeshSurface *f = mesh_fix(lmp, fix_id);
  if (!f) return -1;
  TriMesh *m = f->triMesh();
  NodeC &node = TriMeshAccess::nodes(m);
  NodeC *vc = m->prop().getElementProperty<NodeC>("v");
  FlagC *ea = m->prop().getElementProperty<FlagC>("edgeActive");
  FlagC *ca = m->prop().getElementProperty<FlagC>("cornerActive");
  if (!vc || !ea || !ca) return -1;
  double ***vel = vc->begin();
  const int nall = m->sizeLocal() + m->sizeGhost();
  /* node positions are not forward-communicated: every copy is set here */
  for (int i = 0; i < nall; i++) {
    const int t = m->id(i);
    for (int k = 0; k < 3; k++) {
      const int a = tri[3 * t + k];
      for (int d = 0; d < 3; d++) {
        node(i)[k][d] = x[3 * a + d];
        vel[i][k][d] = v[3 * a + d];
      }
      if (edge_active) (*ea)(i)[k] = edge_active[3 * t + k] != 0;
      if (corner_active) (*ca)(i)[k] = corner_active[3 * t + k] != 0;
    }
  }
  m->updateCenterRbound(0, nall); /* centres, bounding radii, box (MPI) */
  TriMeshAccess::recalc(m);       /* edges, normals, areas (MPI) */
  return 0;
}

extern "C" int lgd_shim_mesh_flags(void *lmp, const char *fix_id, uint8_t *edge_active,
                                   uint8_t *corner_active) {
  FixMeshSurface *f = mesh_fix(lmp, fix_id);
  if (!f) return -1;
  TriMesh *m = f->triMesh();
  for (int i = 0; i < m->sizeLocal(); i++)
    for (int k = 0; k < 3; k++) {
      edge_active[3 * m->id(i) + k] = (uint8_t)(1 + m->edgeActive(i, k));
      corner_active[3 * m->id(i) + k] = (uint8_t)(1 + m->cornerActive(i, k));
    }
  return 0;
}

extern "C" int lgd_shim_mesh_contacts(void *lmp, const char *fix_id, lgd_rows *rows) {
  LAMMPS *l = static_cast<LAMMPS *>(lmp);
  /* the per-contact store of `store_force_contact_stress` (named by the mesh) */
  char id[LGD_ID_LEN + 32];
  snprintf(id, sizeof id, "contactforces_stress_%s", fix_id);
  FixContactHistory *fc = dynamic_cast<FixContactHistory *>(l->modify->find_fix_id(id));
  if (!fc) return -1;
  double **x = l->atom->x, *r = l->atom->radius;
  const int *type = l->atom->type;
  for (int i = 0; i < l->atom->nlocal; i++) {
    const int np = fc->n_partner(i);
    if (np == 0) continue;
    if (lgd_rows_reserve(rows, np)) return -1;
    for (int j = 0; j < np; j++) {
      /* history: force on the grain (3), centre − contact point (3), wall velocity (3) */
      const double *h = fc->contacthistory(i, j);
      double *row = &rows->v[LGD_ROW_LEN * (size_t)rows->n++];
      row[LGD_ROW_TRI] = fc->partner(i, j);
      row[LGD_ROW_TYPE] = type[i];
      row[LGD_ROW_R] = r[i];
      row[LGD_ROW_DIST] = std::sqrt(h[3] * h[3] + h[4] * h[4] + h[5] * h[5]);
      for (int d = 0; d < 3; d++) {
        row[LGD_ROW_CP + d] = x[i][d] - h[3 + d];
        row[LGD_ROW_F + d] = h[d];
      }
    }
  }
  return 0;
}

extern "C" int lgd_shim_mesh_force(void *lmp, const char *fix_id, double *out) {
  FixMeshSurface *f = mesh_fix(lmp, fix_id);
  if (!f) return -1;
  for (int d = 0; d < 3; d++) out[d] = f->compute_vector(d); /* stress module: force ON the mesh */
  return 0;
}

extern "C" void lgd_shim_pair_stats(void *lmp, const double *estar, int ntypes, lgd_stats *st) {
  LAMMPS *l = static_cast<LAMMPS *>(lmp);
  NeighList *list = l->force->pair ? l->force->pair->list : NULL;
  if (!list) return;
  double **x = l->atom->x, *r = l->atom->radius;
  const int *type = l->atom->type, nlocal = l->atom->nlocal;
  for (int ii = 0; ii < list->inum; ii++) {
    const int i = list->ilist[ii];
    const int *jl = list->firstneigh[i];
    for (int jj = 0; jj < list->numneigh[i]; jj++) {
      const int j = jl[jj] & NEIGHMASK;
      const double dx = x[i][0] - x[j][0], dy = x[i][1] - x[j][1], dz = x[i][2] - x[j][2];
      const double d2 = dx * dx + dy * dy + dz * dz, rs = r[i] + r[j];
      if (d2 >= rs * rs) continue; /* most listed pairs do not touch */
      const double overlap = rs - std::sqrt(d2);
      /* newton off: a pair with a ghost is listed on both ranks */
      const double weight = j < nlocal ? 1.0 : 0.5;
      const double rmin = r[i] < r[j] ? r[i] : r[j];
      lgd_stats_add(st, overlap, rmin, r[i] * r[j] / (r[i] + r[j]),
                    estar[(type[i] - 1) * ntypes + type[j] - 1], weight);
      st->pair_contacts += weight;
    }
  }
}

extern "C" void lgd_shim_timer_add(void *lmp, double *acc) {
  const double *t = static_cast<LAMMPS *>(lmp)->timer->array; /* reset by every run */
  const int order[LGD_SHIM_TIMERS] = {TIME_LOOP, TIME_PAIR, TIME_NEIGHBOR, TIME_COMM, TIME_MODIFY, TIME_OUTPUT};
  for (int k = 0; k < LGD_SHIM_TIMERS; k++) acc[k] += t[order[k]];
}

extern "C" void lgd_shim_screen_trim(void *lmp, long max_bytes) {
  FILE *s = static_cast<LAMMPS *>(lmp)->screen;
  if (!s || ftell(s) < max_bytes) return;
  fflush(s);
  if (ftruncate(fileno(s), 0) == 0) rewind(s);
}

/* LIGGGHTS 3.8's write_restart sizes each fix's per-grain data by the fix's
 * maxsize_restart(), from its maxtouch_ (most contacts of any grain). The
 * per-contact stores (FixContactPropertyAtom: `store_force_contact_stress`)
 * update maxtouch_ only in pre_exchange at a re-neighbouring (their
 * setup_pre_exchange does nothing), so between re-neighbourings a grain can
 * hold more contacts than the file's per-grain size says: read_restart then
 * writes past atom->extra (the heap: a crash) and the fixes after it read
 * their data from the wrong place (the grain pairs' tangential history).
 * Recomputing maxtouch_ now (their pre_exchange does only that) makes the
 * sizes right. */
extern "C" void lgd_shim_restart_sizes(void *lmp) {
  Modify *mod = static_cast<LAMMPS *>(lmp)->modify;
  for (int k = 0; k < mod->nfix; k++)
    if (FixContactPropertyAtom *f = dynamic_cast<FixContactPropertyAtom *>(mod->fix[k])) f->pre_exchange();
}
