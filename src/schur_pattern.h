/* SPDX-License-Identifier: BSD-3-Clause */
// Which blocks of the reduced camera system S are nonzero, from the visibility (cameras that
// see a common free point) and the sharing (unknowns a camera touches together), and the AMD
// ordering of that block graph: what the sparse solver stores and factors, and what the choice
// of solver (solver_choice.h) measures.
#ifndef SBA_SRC_SCHUR_PATTERN_H
#define SBA_SRC_SCHUR_PATTERN_H

#include <memory>
#include <vector>

#include "layout.h"

namespace sba {

// S's upper triangle, diagonal included, block column by block column: column B's block rows
// b <= B are rows[colstart[B] .. colstart[B+1]), ascending. Blocks are the free cameras' (sba
// 1.6's layout) or, with shared unknowns, the CameraMap's blocks.
struct SchurPattern {
  std::vector<int> rows;
  std::vector<i64> colstart;

  int nblocks() const { return colstart.empty() ? 0 : int(colstart.size()) - 1; }
  i64 nnz() const { return i64(rows.size()); }
};

// S's pattern into *pat. False, with *pat incomplete, as soon as it holds more than max_blocks
// blocks: a caller that only wants to know whether S is sparse stops there rather than pay for
// (and hold) the pattern of a dense S, whose columns cost the sum of their cameras' track
// lengths each.
bool schur_pattern(const Layout &lay, i64 max_blocks, SchurPattern *pat);

// S's pattern and the AMD order of its block graph, as the choice of solver computes them
// (shape_of, solver_choice.h) and hands them to the sparse solver it chose, which would
// otherwise compute them again.
struct SchurAnalysis {
  SchurPattern pattern;
  std::vector<int> order;  // amd_block_order's
};

// AMD's fill-reducing ordering of the pattern's block graph: order[k] is the block that goes
// to position k. info: null, or AMD_INFO doubles that receive AMD's statistics (among them
// Info[AMD_LNZ], the off-diagonal blocks of the Cholesky factor in that order). Throws
// std::bad_alloc when AMD runs out of memory.
std::vector<int> amd_block_order(const SchurPattern &pat, double *info);

}  // namespace sba

#endif
