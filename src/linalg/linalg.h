/* Requires: core. External: CHOLMOD, ARPACK, LAPACKE/LAPACK/OpenBLAS. */
/* Private access to the CHOLMOD matrix behind km_sparse (prefix km__). */
#ifndef KM_LINALG_SPARSE_H
#define KM_LINALG_SPARSE_H

#include "kinemesh.h"

#include <cholmod.h>

/* The CHOLMOD matrix: CHOLMOD_INT indices, CHOLMOD_REAL double, sorted, packed, stype 0
 * (symmetric matrices store both triangles). Owned by A; do not free or resize it. Its
 * values may be changed in place (same pattern), e.g. to refactorise. */
cholmod_sparse *km__sparse_cholmod(const km_sparse *A);

/* Wraps a CHOLMOD matrix, taking ownership of *C (set to NULL, freed on error too).
 * *C must be CHOLMOD_INT / CHOLMOD_REAL / CHOLMOD_DOUBLE with stype 0; it is sorted and
 * packed here if it is not already. */
km_status km__sparse_from_cholmod(cholmod_sparse **C, km_sparse **out, km_error *err);

/* Finishes a CSC matrix whose columns were filled bucket-wise: *C is packed (p has ncol+1
 * entries, p[ncol] = entries), rows within a column unsorted and possibly repeated. Sorts
 * each column (stable), sums repeated rows in fill order, then wraps it as km__sparse_from_cholmod
 * does (takes ownership). Linear in the entries for short columns. */
km_status km__sparse_compress(cholmod_sparse **C, km_sparse **out, km_error *err);

/* cholmod_start plus the settings every kinemesh common uses (int indices, never prints). */
void km__cholmod_start(cholmod_common *cc);

/* Mutable values array (nnz entries, CSC order) for in-place updates of the same pattern. */
double *km__sparse_values(km_sparse *A);

#endif
