/* SPDX-License-Identifier: BSD-3-Clause */
// The reduced camera system over shared unknowns (camera_map.h): S = U + mu I - Z V*^-1 Z^T
// and rhs = e_a - Z V*^-1 e_b, where a camera's parameters map to the unknowns of the blocks
// it touches. U's block (b, B) is the sum over the cameras touching both of their U_j's
// entries for b's and B's parameters; Z_ib, point i's coupling to block b, sums W_ij over
// the projections of i whose camera touches b. Two blocks are coupled when one camera
// touches both or when cameras touching them see a common point: a block shared by many
// cameras is one block of S, not a border around it, and costs what a camera costs.
//
// The per-camera kernels (kernels.h) stay the ones for sba 1.6's layout; this is the
// assembly for a layout with sharing, with block sizes known at run time.
#ifndef SBA_SRC_MAPPED_SCHUR_H
#define SBA_SRC_MAPPED_SCHUR_H

#include <memory>
#include <vector>

#include "kernels.h"
#include "layout.h"
#include "parallel.h"

namespace sba {

// Where the assembly finds block (b, B), b <= B, of S over the unknowns' blocks.
//  - Dense: row-major in an nU x nU matrix of row stride ld; the upper block triangle is
//    filled (zeroed by the assembly itself), diagonal blocks whole.
//  - Sparse: the lower triangle of P S P^T in compressed columns, as kernels.h's BlockMap but
//    with blocks of their own sizes: block column c (of P S P^T) has size(c) scalar columns,
//    each height[c] entries long, holding the block rows rows[colstart[c] .. colstart[c+1])
//    (ascending, c first), the one at s starting rowoff[s] into the column; the column
//    starts at colbase[c]. Zeroed by the caller.
//  - Clusters: the blocks of S's principal submatrices over disjoint sets of blocks (each
//    block in exactly one, alone or with others): block b's cluster holds b's rows from
//    row pos[b] of its order[b] x order[b] row-major matrix at base + origin[b], the blocks
//    in ascending order. Block (b, B) is held when b and B are in one cluster (the same
//    origin); the upper block triangle is filled, diagonal blocks whole. Zeroed by the caller.
struct UnknownBlocks {
  enum class Kind { Dense, Sparse, Clusters };
  Kind kind = Kind::Dense;
  double *base = nullptr;
  i64 ld = 0;
  const i64 *start = nullptr;  // block b's first unknown: CameraMap::block_starts
  const int *perm = nullptr, *rows = nullptr;
  const i64 *colstart = nullptr, *colbase = nullptr, *height = nullptr, *rowoff = nullptr;
  const i64 *origin = nullptr;
  const int *pos = nullptr, *order = nullptr;

  // Whether block (b, B), b <= B, is held.
  bool holds(int b, int B) const { return kind != Kind::Clusters || origin[b] == origin[B]; }

  struct Block {
    double *p;
    i64 ld;
    bool transposed;  // holds block (B, b) instead
  };
  Block block(int b, int B) const;
};

class MappedSchur {
 public:
  // How a dense S takes the points' terms: by the rule of tiled() (Auto), or always point by
  // point, or always tile by tile; the two give the same bits.
  enum class Assembly { Auto, PointByPoint, Tiled };

  // For a layout with shared unknowns and free points or not; threads: the pool's size;
  // tile: the tiles' width in unknowns (a tile holds one block at least); chunk: the most
  // points in a chunk.
  MappedSchur(const Layout &lay, int threads, Assembly how = Assembly::Auto, int tile = 24, int chunk = 512);

  // Point i's blocks, ascending (the map's index).
  const int *point_blocks(int i) const { return lay_.cams.point_blocks(i); }
  int point_nblocks(int i) const { return lay_.cams.point_nblocks(i); }

  // The blocks of S that `S` holds and (unless null) rhs over the unknowns, at damping mu;
  // Vinv: every free point's (V_i + mu I)^-1 (Kernels::invert_damped_V).
  void assemble(ThreadPool &pool, const NormalEquations &ne, const double *Vinv, double mu,
                const UnknownBlocks &S, double *rhs) const;

  // Z_ib^T (pnp x size_b, row-major) of point i's first `upto` blocks, block s's at
  // Zt + zoff[s] (zoff: the running sums of the blocks' sizes times pnp, zoff[0] = 0, upto + 1
  // of them); W: pnp x cnp scratch.
  void point_couplings(const double *jac, int i, int upto, const i64 *zoff, double *Zt, double *W) const;

  // The number of doubles point_couplings writes for any point, all of its blocks.
  i64 max_couplings() const { return zmax_; }

  const Layout &layout() const { return lay_; }

  // Whether the points touch so much of S that a dense S is better assembled tile by tile, a
  // chunk of points at a time, than point by point; the tiles' boundaries in blocks (ngroups
  // + 1 of them, from 0 to the number of blocks).
  bool tiled() const { return tiled_; }
  const int *tile_groups() const { return groups_.data(); }
  int tile_ngroups() const { return int(groups_.size()) - 1; }

  // A chunk of points for the tiled assembly: for the c-th, its point, its block range
  // [lo, hi) in the columns being assembled, where its Z^T and Y^T start in buf and its
  // offsets in zoff, and its cursor in its blocks; and a tile's tables (width: the widest
  // tile's blocks, times the chunk's points): each column block's points (count, their
  // indices in the chunk, their Y^T) and each row block's Z^T by point (null for a point that
  // does not touch it).
  struct Chunk {
    // Left undefined, not cleared: every use writes it before reading it, and a small
    // problem solved over and over (a mapper's local adjustments) should not pay for
    // clearing it each time.
    std::unique_ptr<double[]> buf;
    i64 buf_size = 0;
    std::vector<i64> zoff, base, zbase;
    std::vector<int> point, lo, hi, cur;
    std::vector<int> ycount, yc;
    std::vector<const double *> yp, zp;
  };

  // One thread's room for a point's couplings (Z^T, Y^T, their offsets) and one W^T.
  struct Scratch {
    std::vector<double> Zt, Yt, W;
    std::vector<i64> zoff;
    Chunk chunk;  // held only when tiled()
  };

 private:
  const Layout &lay_;
  bool avx2_ = false;                  // the AVX2 build of the loops runs (isa.h)
  std::vector<int> split_;             // threads + 1 boundaries in blocks, of about equal work
  i64 zmax_ = 0;
  bool tiled_ = false;
  std::vector<int> groups_;
  int group_width_ = 0;  // the most blocks in a tile group
  mutable std::vector<Scratch> scratch_;
};

// The loops, in the build for any x86-64 (portable) and for AVX2 with FMA (avx2):
// mapped_schur_impl.h. Block columns [B0, B1) of S and their rows of rhs, as assemble().
namespace portable {
void mapped_assemble_columns(const MappedSchur &ms, int B0, int B1, const NormalEquations &ne, const double *Vinv,
                             double mu, const UnknownBlocks &S, double *rhs, MappedSchur::Scratch &sc);
void mapped_point_couplings(const MappedSchur &ms, const double *jac, int i, int upto, const i64 *zoff, double *Zt,
                            double *W);
}  // namespace portable
namespace avx2 {
void mapped_assemble_columns(const MappedSchur &ms, int B0, int B1, const NormalEquations &ne, const double *Vinv,
                             double mu, const UnknownBlocks &S, double *rhs, MappedSchur::Scratch &sc);
void mapped_point_couplings(const MappedSchur &ms, const double *jac, int i, int upto, const i64 *zoff, double *Zt,
                            double *W);
}  // namespace avx2

}  // namespace sba

#endif
