/* cli layer: command-line options of bin/i2m. */
#ifndef I2M_CLI_OPTIONS_H
#define I2M_CLI_OPTIONS_H

#include "i2m/refine.h"

#define I2M_MAX_LIST 64

typedef struct {
  const char *input, *output, *report, *trace;
  i2m_refine_params_t params;
  i2m_label_size_t label_sizes[I2M_MAX_LIST];
  i2m_region_t regions[I2M_MAX_LIST];
  int quiet, verbose, check, threads, no_pin, deterministic;
  int allow_external_data; /* --allow-external-data */
  int vtu_raw;         /* --vtu-raw: VTU data not compressed */
  int depth;           /* the octree's depth (0: the default) */
  double coarse_factor;
  double max_memory; /* --max-memory in bytes (0: the machine's memory and limits) */
  double sliver_angle; /* 0: no sliver perturbation */
  int msh_version;     /* --msh-format: 41 or 22 (0: the writers' default) */
  int ascii;           /* --ascii: a text .msh */
  int help, version;
} cli_options_t;

/** Parses argv; on error returns I2M_ERR_ARG with a message naming the option. */
i2m_err_t cli_parse(int argc, char **argv, cli_options_t *o);
void cli_usage(FILE *f);

#endif
