/* i2m api layer (layer 8): the mesher's steps from a label image to the extracted mesh
 * (distance transform, refinement by threads or by ranks, sliver pass, fragments, census,
 * extraction), shared by bin/i2m and the library call i2m_mesh_labels (include/i2m.h).
 * Collective over par's ranks when the run is distributed. */
#ifndef I2M_PIPELINE_H
#define I2M_PIPELINE_H

#include "i2m/dist.h"
#include "i2m/edt.h"
#include "i2m/report.h"

#ifdef __cplusplus
extern "C" {
#endif

/** What the steps need besides the image. */
typedef struct {
  i2m_refine_params_t params;
  int threads;          /**< 0: the default */
  int depth;            /**< the octree's depth (0: the default) */
  double coarse_factor; /**< the coarse mesh's size bound, times the target */
  double sliver_angle;  /**< 0: no sliver perturbation */
  double max_memory;    /**< bytes (0: the machine's memory and limits) */
  bool pin, deterministic;
  bool check;           /**< check the triangulation before extraction (--check) */
  bool checksum;        /**< compute the triangulation's checksum (for the JSON report) */
  const char *trace;    /**< --trace file, or NULL */
  bool spread_output;   /**< distributed: each rank writes its own piece, spread the tets evenly */
} i2m_pipeline_opts_t;

/** A run: its inputs, what the steps produce, and their timings. */
typedef struct {
  const i2m_par_t *par;  /**< borrowed */
  bool distributed;      /**< the dist layer refines (started under MPI) */
  i2m_pipeline_opts_t opt;
  i2m_image_t *img;      /**< borrowed; its voxels are released by i2m_pipeline_mesh */
  i2m_edt_t *edt;
  i2m_refine_t *ref;
  i2m_tetmesh_t *mesh;   /**< the extracted mesh (this rank's piece when distributed) */
  i2m_label_pieces_t *pieces; /**< per label: image components and mesh pieces */
  i2m_threads_report_t team;
  i2m_dist_report_t dist;
  i2m_sliver_stats_t slivers;
  i2m_dihedral_bands_t bands_before; /**< with a sliver pass: the bands before it (summed over the ranks) */
  uint64_t checksum;     /**< with opt.checksum: of the whole triangulation (summed over ranks) */
  int64_t working_tets;
  double phase_seconds[I2M_NPHASES];
  double tphase;
} i2m_pipeline_t;

/** Refuses, before any work, a run whose estimated size does not fit in memory (or in
 *  opt->max_memory), with the estimate in the message. */
i2m_err_t i2m_pipeline_check_estimate(const i2m_par_t *par, const i2m_image_t *img, const i2m_pipeline_opts_t *opt);

/** A phase's start and end: its time goes to p->phase_seconds[phase]; debug lines say so. */
void i2m_pipeline_phase_begin(i2m_pipeline_t *p, const char *what);
void i2m_pipeline_phase_end(i2m_pipeline_t *p, int phase);

/** From the image to p->mesh (phases EDT, REFINE, SLIVERS, EXTRACT).  Errors are agreed on
 *  across the ranks. */
i2m_err_t i2m_pipeline_mesh(i2m_pipeline_t *p);

/** Frees what the steps made (not the image); accepts a zeroed run. */
void i2m_pipeline_free(i2m_pipeline_t *p);

#ifdef __cplusplus
}
#endif
#endif
