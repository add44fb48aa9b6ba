/* CHOLMOD behind km_sparse and km_cholesky: private to src/linalg/ (the one door to CHOLMOD). */
#ifndef KM_LINALG_CHOLMOD_DOOR_H
#define KM_LINALG_CHOLMOD_DOOR_H

#include "linalg/linalg.h"

#include <cholmod.h>

/* The CHOLMOD matrix: CHOLMOD_INT indices, CHOLMOD_REAL double, sorted, packed, stype 0
 * (symmetric matrices store both triangles, unless km__cholesky_options.stored says one).
 * Owned by A; do not free or resize it. Its values may be changed in place (same pattern). */
cholmod_sparse *km__sparse_cholmod(const km_sparse *A);

/* Wraps a CHOLMOD matrix, taking ownership of *C (set to NULL, freed on error too).
 * *C must be CHOLMOD_INT / CHOLMOD_REAL / CHOLMOD_DOUBLE with stype 0; it is sorted and
 * packed here if it is not already. */
km_status km__sparse_from_cholmod(cholmod_sparse **C, km_sparse **out, km_error *err);

/* cholmod_start plus the settings every kinemesh common uses (int indices, never prints). */
void km__cholmod_start(cholmod_common *cc);

#endif
