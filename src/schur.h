// The pieces of the Schur-complement step shared by the dense and sparse S solvers:
// the damped point blocks V*_i^-1, the reduced camera system S da = r, and the point
// back-substitution db_i = V*_i^-1 (e_b,i - sum_j W_ij^T da_j).
#ifndef SBA_SRC_SCHUR_H
#define SBA_SRC_SCHUR_H

#include <vector>

#include "linsolve.h"

namespace sba::schur {

// W_ij = A_ij^T B_ij (cnp x pnp, row-major) of projection k.
void form_W(const Layout &lay, const double *jac, i64 k, double *W);

// Per-solve scratch of the Schur assembly, sized once.
class Assembler {
 public:
  explicit Assembler(const Layout &lay);

  // V*_i^-1 = (V_i + mu I)^-1 for every free point; false if one is not positive definite.
  bool invert_damped_V(const NormalEquations &ne, double mu);

  // Builds S = U* - sum_i Y_i W_i^T (upper block triangle only) and r = e_a - sum Y_ij e_b,i
  // over the free cameras. `block(j, k)` (j <= k, camera indices relative to mcon) returns a
  // pointer to the row-major cnp x cnp block S_jk and its row stride; the blocks must hold
  // zeros on entry. rhs: free cameras' entries, (m - mcon) * cnp.
  template <class BlockFn>
  void assemble(const NormalEquations &ne, double mu, BlockFn block, double *rhs);

  // db for the free points from da (dp's camera part) into dp.
  void back_substitute(const NormalEquations &ne, double *dp);

 private:
  const Layout &lay_;
  std::vector<double> Vinv_;   // n * pnp^2
  std::vector<double> W_, Y_;  // one track's W_ij and Y_ij = W_ij V*_i^-1
  std::vector<i64> track_;     // the free-camera projections of the current point
  std::vector<double> tmp_;
};

template <class BlockFn>
void Assembler::assemble(const NormalEquations &ne, double mu, BlockFn block, double *rhs) {
  const Layout &lay = lay_;
  const int cnp = lay.cnp, pnp = lay.pnp;
  const i64 cp = i64(cnp) * pnp;
  for (int j = lay.mcon; j < lay.m; ++j) {
    const int jr = j - lay.mcon;
    i64 ld = 0;
    double *S = block(jr, jr, &ld);
    const double *U = ne.U + i64(j) * cnp * cnp;
    for (int a = 0; a < cnp; ++a) {
      for (int b = a; b < cnp; ++b) S[a * ld + b] = U[a * cnp + b];
      S[a * ld + a] += mu;
    }
    for (int a = 0; a < cnp; ++a) rhs[i64(jr) * cnp + a] = ne.ea[i64(j) * cnp + a];
  }
  for (int i = lay.ncon; i < lay.n; ++i) {
    int nt = 0;
    for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k)
      if (lay.colidx[k] >= lay.mcon) track_[size_t(nt++)] = k;
    if (nt == 0) continue;
    const double *Vi = Vinv_.data() + i64(i) * pnp * pnp;
    const double *ebi = ne.eb + i64(i) * pnp;
    for (int t = 0; t < nt; ++t) {
      double *W = W_.data() + t * cp, *Y = Y_.data() + t * cp;
      form_W(lay, ne.jac, track_[size_t(t)], W);
      for (int a = 0; a < cnp; ++a)
        for (int b = 0; b < pnp; ++b) {
          double s = 0.0;
          for (int c = 0; c < pnp; ++c) s += W[a * pnp + c] * Vi[c * pnp + b];
          Y[a * pnp + b] = s;
        }
    }
    for (int t1 = 0; t1 < nt; ++t1) {
      const int j1 = lay.colidx[track_[size_t(t1)]] - lay.mcon;
      const double *Y = Y_.data() + t1 * cp;
      for (int a = 0; a < cnp; ++a) {
        double s = 0.0;
        for (int c = 0; c < pnp; ++c) s += Y[a * pnp + c] * ebi[c];
        rhs[i64(j1) * cnp + a] -= s;
      }
      // Cameras ascend along a track, so t2 >= t1 visits S's upper block triangle.
      for (int t2 = t1; t2 < nt; ++t2) {
        const int j2 = lay.colidx[track_[size_t(t2)]] - lay.mcon;
        const double *W2 = W_.data() + t2 * cp;
        i64 ld = 0;
        double *S = block(j1, j2, &ld);
        for (int a = 0; a < cnp; ++a)
          for (int b = (t2 == t1 ? a : 0); b < cnp; ++b) {
            double s = 0.0;
            for (int c = 0; c < pnp; ++c) s += Y[a * pnp + c] * W2[b * pnp + c];
            S[a * ld + b] -= s;
          }
      }
    }
  }
}

}  // namespace sba::schur

#endif
