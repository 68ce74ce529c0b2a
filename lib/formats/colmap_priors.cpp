// SPDX-License-Identifier: BSD-3-Clause
#include "formats/colmap_priors.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <unordered_map>
#include <unordered_set>

#include "cameras/camera_pose.h"
#include "cameras/colmap_camera.h"
#include "formats/text_tokens.h"

namespace sbaformats::colmap {
namespace {

using Vec3 = std::array<double, 3>;

// The lines of a text file that hold something, each as its tokens and its line number.
struct Line {
  int number = 0;
  std::vector<std::string> tokens;
};

void lines_of(const std::string &text, std::vector<Line> *out) {
  int number = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    ++number;
    Line line{number, {}};
    std::size_t k = pos;
    while (k < end) {
      while (k < end && (text[k] == ' ' || text[k] == '\t' || text[k] == '\r')) ++k;
      const std::size_t b = k;
      while (k < end && text[k] != ' ' && text[k] != '\t' && text[k] != '\r') ++k;
      if (k > b) line.tokens.emplace_back(text, b, k - b);
    }
    if (!line.tokens.empty() && line.tokens[0][0] != '#') out->push_back(std::move(line));
    pos = end + 1;
  }
}

std::string at(const std::string &path, const Line &line) { return path + ":" + std::to_string(line.number) + ": "; }

bool finite_value(const std::string &tok, const std::string &what, const std::string &where, double *out,
                  std::string *error) {
  if (decimal_number(tok, out) && std::isfinite(*out)) return true;
  *error = where + what + " must be a finite number, got '" + TextTokens::printable(tok) + "'";
  return false;
}

// A whole number in [0, hi], plain decimal digits.
bool id_value(const std::string &tok, const std::string &what, const std::string &where, std::uint64_t hi,
              std::uint64_t *out, std::string *error) {
  bool digits = !tok.empty() && tok.size() <= 19;
  for (char c : tok) digits = digits && c >= '0' && c <= '9';
  const unsigned long long v = digits ? std::strtoull(tok.c_str(), nullptr, 10) : 0;
  if (!digits || v > hi) {
    *error = where + what + " must be a whole number in 0.." + std::to_string(hi) + ", got '" +
             TextTokens::printable(tok) + "'";
    return false;
  }
  *out = v;
  return true;
}

// Solves the symmetric positive definite n x n system H x = g (row-major) in place of g by
// Cholesky's factorization; false when a pivot is not positive.
template <int n>
bool solve_spd(std::array<double, n * n> H, std::array<double, n> *g) {
  for (int j = 0; j < n; ++j) {
    for (int k = 0; k < j; ++k) H[j * n + j] -= H[j * n + k] * H[j * n + k];
    if (!(H[j * n + j] > 0)) return false;
    H[j * n + j] = std::sqrt(H[j * n + j]);
    for (int i = j + 1; i < n; ++i) {
      for (int k = 0; k < j; ++k) H[i * n + j] -= H[i * n + k] * H[j * n + k];
      H[i * n + j] /= H[j * n + j];
    }
  }
  for (int i = 0; i < n; ++i) {  // L y = g
    for (int k = 0; k < i; ++k) (*g)[i] -= H[i * n + k] * (*g)[k];
    (*g)[i] /= H[i * n + i];
  }
  for (int i = n - 1; i >= 0; --i) {  // L^T x = y
    for (int k = i + 1; k < n; ++k) (*g)[i] -= H[k * n + i] * (*g)[k];
    (*g)[i] /= H[i * n + i];
  }
  return true;
}

// Whether the row-major 3x3 c is symmetric (to rounding) and positive definite: its Cholesky
// factor exists.
bool symmetric_positive_definite(const std::array<double, 9> &c) {
  double scale = 0;
  for (double v : c) {
    if (!std::isfinite(v)) return false;
    scale = std::max(scale, std::fabs(v));
  }
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < r; ++k)
      if (std::fabs(c[r * 3 + k] - c[k * 3 + r]) > 1e-9 * scale) return false;
  std::array<double, 3> x{};
  return solve_spd<3>(c, &x);
}

std::string covariance_message(const std::array<double, 9> &c) {
  for (double v : c)
    if (!std::isfinite(v)) return "its covariance has a value that is not finite";
  return "its covariance is not symmetric positive definite";
}

// --- the similarity ---

// The eigenvector of the largest eigenvalue of the symmetric 4x4 N, by Jacobi's rotations.
std::array<double, 4> largest_eigenvector(std::array<double, 16> N) {
  std::array<double, 16> V{};
  for (int k = 0; k < 4; ++k) V[k * 4 + k] = 1;
  for (int sweep = 0; sweep < 50; ++sweep) {
    double off = 0, diag = 0;
    for (int p = 0; p < 4; ++p) {
      diag += N[p * 4 + p] * N[p * 4 + p];
      for (int q = p + 1; q < 4; ++q) off += N[p * 4 + q] * N[p * 4 + q];
    }
    if (off <= 1e-30 * diag || off == 0) break;
    for (int p = 0; p < 4; ++p)
      for (int q = p + 1; q < 4; ++q) {
        const double apq = N[p * 4 + q];
        if (apq == 0) continue;
        const double theta = (N[q * 4 + q] - N[p * 4 + p]) / (2 * apq);
        const double t = (theta >= 0 ? 1 : -1) / (std::fabs(theta) + std::sqrt(theta * theta + 1));
        const double c = 1 / std::sqrt(t * t + 1), s = t * c;
        for (int k = 0; k < 4; ++k) {  // N <- N J
          const double a = N[k * 4 + p], b = N[k * 4 + q];
          N[k * 4 + p] = c * a - s * b;
          N[k * 4 + q] = s * a + c * b;
        }
        for (int k = 0; k < 4; ++k) {  // N <- J^T N
          const double a = N[p * 4 + k], b = N[q * 4 + k];
          N[p * 4 + k] = c * a - s * b;
          N[q * 4 + k] = s * a + c * b;
        }
        for (int k = 0; k < 4; ++k) {
          const double a = V[k * 4 + p], b = V[k * 4 + q];
          V[k * 4 + p] = c * a - s * b;
          V[k * 4 + q] = s * a + c * b;
        }
      }
  }
  int best = 0;
  for (int k = 1; k < 4; ++k)
    if (N[k * 4 + k] > N[best * 4 + best]) best = k;
  return {V[0 * 4 + best], V[1 * 4 + best], V[2 * 4 + best], V[3 * 4 + best]};
}

// The least-squares similarity dst ~ s R src + t over the pairs `use` (Horn's closed form with
// quaternions, the scale as Umeyama's): false when the source points coincide.
bool fit_similarity(const std::vector<Vec3> &src, const std::vector<Vec3> &dst, const std::vector<int> &use,
                    Similarity *out) {
  const double n = static_cast<double>(use.size());
  Vec3 ms{}, md{};
  for (int k : use)
    for (int a = 0; a < 3; ++a) {
      ms[a] += src[k][a] / n;
      md[a] += dst[k][a] / n;
    }
  double S[9] = {}, var = 0;
  for (int k : use) {
    Vec3 x, y;
    for (int a = 0; a < 3; ++a) {
      x[a] = src[k][a] - ms[a];
      y[a] = dst[k][a] - md[a];
      var += x[a] * x[a];
    }
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) S[a * 3 + b] += x[a] * y[b];
  }
  if (!(var > 0) || !std::isfinite(var)) return false;
  const double Sxx = S[0], Sxy = S[1], Sxz = S[2], Syx = S[3], Syy = S[4], Syz = S[5], Szx = S[6], Szy = S[7],
               Szz = S[8];
  const std::array<double, 16> N = {Sxx + Syy + Szz, Syz - Szy,       Szx - Sxz,        Sxy - Syx,
                                    Syz - Szy,       Sxx - Syy - Szz, Sxy + Syx,        Szx + Sxz,
                                    Szx - Sxz,       Sxy + Syx,       -Sxx + Syy - Szz, Syz + Szy,
                                    Sxy - Syx,       Szx + Sxz,       Syz + Szy,        -Sxx - Syy + Szz};
  const std::array<double, 4> q = largest_eigenvector(N);
  Similarity r;
  sbacameras::euclidean::rotation_matrix(sbacameras::euclidean::normalized_rotation({q[0], q[1], q[2], q[3]}),
                                         r.R.data());
  double dot = 0;
  for (int k : use)
    for (int a = 0; a < 3; ++a) {
      double rx = 0;
      for (int b = 0; b < 3; ++b) rx += r.R[a * 3 + b] * (src[k][b] - ms[b]);
      dot += (dst[k][a] - md[a]) * rx;
    }
  r.s = dot / var;
  if (!(r.s > 0) || !std::isfinite(r.s)) return false;
  for (int a = 0; a < 3; ++a) {
    double rm = 0;
    for (int b = 0; b < 3; ++b) rm += r.R[a * 3 + b] * ms[b];
    r.t[a] = md[a] - r.s * rm;
  }
  *out = r;
  return true;
}

Vec3 transformed(const Similarity &x, const Vec3 &p) {
  Vec3 q;
  for (int a = 0; a < 3; ++a)
    q[a] = x.s * (x.R[a * 3] * p[0] + x.R[a * 3 + 1] * p[1] + x.R[a * 3 + 2] * p[2]) + x.t[a];
  return q;
}

double distance(const Vec3 &a, const Vec3 &b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

std::vector<int> inliers_of(const Similarity &x, const std::vector<Vec3> &src, const std::vector<Vec3> &dst,
                            double max_error) {
  std::vector<int> in;
  for (std::size_t k = 0; k < src.size(); ++k)
    if (distance(transformed(x, src[k]), dst[k]) <= max_error) in.push_back(static_cast<int>(k));
  return in;
}

// Whether three points span a plane: the triangle's area is not negligible beside its sides.
bool spans_plane(const Vec3 &a, const Vec3 &b, const Vec3 &c) {
  const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const Vec3 w{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  const double uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2], vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  return w[0] * w[0] + w[1] * w[1] + w[2] * w[2] > 1e-12 * uu * vv;
}

constexpr double kDegree = 3.14159265358979323846 / 180;

Vec3 wgs84_to_ecef(const Vec3 &lla) {
  constexpr double a = 6378137.0, f = 1 / 298.257223563, e2 = f * (2 - f);
  const double lat = lla[0] * kDegree, lon = lla[1] * kDegree, h = lla[2];
  const double N = a / std::sqrt(1 - e2 * std::sin(lat) * std::sin(lat));
  return {(N + h) * std::cos(lat) * std::cos(lon), (N + h) * std::cos(lat) * std::sin(lon),
          (N * (1 - e2) + h) * std::sin(lat)};
}

}  // namespace

bool read_pose_priors_text(const std::string &path, const Model &model, std::vector<PosePrior> *out,
                           int *unknown, std::string *error) {
  std::string text;
  return read_whole_file(path, true, &text, error) && parse_pose_priors_text(text, path, model, out, unknown, error);
}

bool parse_pose_priors_text(const std::string &text, const std::string &path, const Model &model,
                            std::vector<PosePrior> *out, int *unknown, std::string *error) {
  *unknown = 0;
  std::vector<Line> lines;
  lines_of(text, &lines);
  std::unordered_map<std::string, std::uint32_t> by_name;
  for (const Image &im : model.images) by_name.emplace(im.name, im.id);
  out->clear();
  for (const Line &line : lines) {
    const std::string where = at(path, line);
    std::vector<std::string> t = line.tokens;
    PosePrior p;
    p.where = path + ":" + std::to_string(line.number);
    p.system = PriorSystem::Cartesian;
    double probe = 0;
    if (t.size() == 5 || t.size() == 14) {
      if (t.back() == "CARTESIAN") p.system = PriorSystem::Cartesian;
      else if (t.back() == "WGS84") p.system = PriorSystem::Wgs84;
      else if (!decimal_number(t.back(), &probe)) {
        *error = where + "the coordinate system must be CARTESIAN or WGS84, got '" +
                 TextTokens::printable(t.back()) + "'";
        return false;
      }
      if (!decimal_number(t.back(), &probe)) t.pop_back();
    }
    if (t.size() != 4 && t.size() != 13) {
      *error = where + "expected NAME X Y Z, then optionally the 9 values of a covariance and CARTESIAN or WGS84 "
                       "(got " + std::to_string(line.tokens.size()) + " values)";
      return false;
    }
    const auto image = by_name.find(t[0]);
    if (image != by_name.end()) p.image_id = image->second;
    static const char *const kAxes[] = {"X", "Y", "Z"};
    for (int a = 0; a < 3; ++a)
      if (!finite_value(t[1 + static_cast<std::size_t>(a)], kAxes[a], where, &p.position[static_cast<std::size_t>(a)], error))
        return false;
    if (t.size() == 13) {
      p.has_covariance = true;
      for (std::size_t k = 0; k < 9; ++k)
        if (!finite_value(t[4 + k], "covariance value " + std::to_string(k + 1), where, &p.covariance[k], error))
          return false;
    }
    if (image != by_name.end()) out->push_back(p);
    else ++*unknown;
  }
  return true;
}

void wgs84_to_enu(std::vector<PosePrior> *priors) {
  const PosePrior *ref = nullptr;
  for (const PosePrior &p : *priors)
    if (p.system == PriorSystem::Wgs84) {
      ref = &p;
      break;
    }
  if (!ref) return;
  const Vec3 origin = wgs84_to_ecef(ref->position);
  const double lat = ref->position[0] * kDegree, lon = ref->position[1] * kDegree;
  const double sl = std::sin(lat), cl = std::cos(lat), so = std::sin(lon), co = std::cos(lon);
  // Rows: east, north, up in ECEF.
  const double R[9] = {-so, co, 0, -sl * co, -sl * so, cl, cl * co, cl * so, sl};
  std::vector<Vec3> enu;
  for (const PosePrior &p : *priors) {
    if (p.system != PriorSystem::Wgs84) continue;
    const Vec3 e = wgs84_to_ecef(p.position);
    const Vec3 d{e[0] - origin[0], e[1] - origin[1], e[2] - origin[2]};
    enu.push_back({R[0] * d[0] + R[1] * d[1] + R[2] * d[2], R[3] * d[0] + R[4] * d[1] + R[5] * d[2],
                   R[6] * d[0] + R[7] * d[1] + R[8] * d[2]});
  }
  std::size_t k = 0;
  for (PosePrior &p : *priors)
    if (p.system == PriorSystem::Wgs84) {
      p.position = enu[k++];
      p.system = PriorSystem::Cartesian;
    }
}

bool usable_pose_priors(const Model &model, const std::vector<PosePrior> &priors, const PosePriorOptions &options,
                        std::vector<PosePrior> *out, std::string *error) {
  const double sd = options.fallback_stddev;
  if (!(sd > 0) || !(sd * sd > 0) || !std::isfinite(sd * sd)) {
    *error = "the fallback standard deviation of the position priors must be finite and > 0";
    return false;
  }
  std::unordered_map<std::uint32_t, bool> sees;  // image id: whether it sees a point
  for (const Image &im : model.images) {
    bool any = false;
    for (const Point2D &pt : im.points) any = any || pt.point3d_id != kNoPoint;
    sees.emplace(im.id, any);
  }
  std::unordered_set<std::uint32_t> seen;
  out->clear();
  for (const PosePrior &p : priors) {
    const auto image = sees.find(p.image_id);
    if (image == sees.end()) continue;
    if (!seen.insert(p.image_id).second) {
      *error = p.where + ": image " + std::to_string(p.image_id) + " has a position prior already";
      return false;
    }
    // COLMAP's default position, all NaN, means none: a prior of something else (a gravity).
    if (std::isnan(p.position[0]) && std::isnan(p.position[1]) && std::isnan(p.position[2])) continue;
    for (double v : p.position)
      if (!std::isfinite(v)) {
        *error = p.where + ": its position is not finite";
        return false;
      }
    PosePrior q = p;
    bool finite = p.has_covariance;
    for (double v : p.covariance) finite = finite && std::isfinite(v);
    if (!finite) {
      q.covariance = {sd * sd, 0, 0, 0, sd * sd, 0, 0, 0, sd * sd};
      q.has_covariance = true;
    } else if (!symmetric_positive_definite(q.covariance)) {
      *error = p.where + ": " + covariance_message(q.covariance);
      return false;
    }
    if (image->second) out->push_back(q);
  }
  return true;
}

bool robust_similarity(const std::vector<Vec3> &src, const std::vector<Vec3> &dst, double max_error,
                       Similarity *out, int *inliers) {
  const int n = static_cast<int>(src.size());
  if (n < 3 || dst.size() != src.size()) return false;
  std::vector<int> all(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) all[static_cast<std::size_t>(k)] = k;
  // A candidate refitted on its inliers until they no longer change (the local optimization
  // of LO-RANSAC), and kept if it holds more pairs within max_error than the best so far, or
  // as many closer in sum of squares: a triple's fit is noisy, and its inliers' fit is not.
  std::vector<int> best;
  double best_sq = 0;
  Similarity best_x;
  bool found = false;
  const auto consider = [&](Similarity x) {
    std::vector<int> in = inliers_of(x, src, dst, max_error);
    for (int round = 0; round < 10 && in.size() >= 3; ++round) {
      Similarity y;
      if (!fit_similarity(src, dst, in, &y)) break;
      std::vector<int> next = inliers_of(y, src, dst, max_error);
      if (next.size() < in.size()) break;
      x = y;
      const bool same = next == in;
      in = std::move(next);
      if (same) break;
    }
    double sq = 0;
    for (int k : in) {
      const double d = distance(transformed(x, src[static_cast<std::size_t>(k)]), dst[static_cast<std::size_t>(k)]);
      sq += d * d;
    }
    if (!found || in.size() > best.size() || (in.size() == best.size() && sq < best_sq)) {
      best = std::move(in);
      best_sq = sq;
      best_x = x;
      found = true;
    }
  };
  // The least-squares fit of every pair first: with no outlier it is the answer.
  Similarity x0;
  if (fit_similarity(src, dst, all, &x0)) consider(x0);
  std::mt19937_64 random(0x5ba);
  const int max_trials = 10000;
  double needed = max_trials;
  for (int trial = 0; trial < max_trials && trial < needed && best.size() < all.size(); ++trial) {
    const std::size_t a = random() % static_cast<unsigned>(n), b = random() % static_cast<unsigned>(n),
                      c = random() % static_cast<unsigned>(n);
    if (a == b || b == c || a == c || !spans_plane(src[a], src[b], src[c])) continue;
    Similarity x;
    if (!fit_similarity(src, dst, {static_cast<int>(a), static_cast<int>(b), static_cast<int>(c)}, &x)) continue;
    consider(x);
    // Trials until a triple of inliers is drawn with 99% confidence (all of them while there is
    // no consensus yet).
    const double w = static_cast<double>(best.size()) / n;
    const double miss = 1 - w * w * w;
    if (best.size() >= 3) needed = miss <= 0 ? 0 : std::min<double>(max_trials, std::log(0.01) / std::log(miss));
  }
  if (!found) return false;
  *out = best_x;
  *inliers = best.size() >= 3 ? static_cast<int>(best.size()) : 0;
  return true;
}

namespace {

// The priors' cost of the points y: sum over k of rho(e^T W_k e), e = y_k - dst_k, W_k the
// inverse of the k-th covariance, rho the loss (Cauchy's c^2 log(1 + s / c^2), or s); the
// weights rho'(s) into *weight when given.
double priors_cost(const std::vector<Vec3> &y, const std::vector<Vec3> &dst, const std::vector<std::array<double, 9>> &W,
                   double cauchy2, std::vector<double> *weight) {
  double cost = 0;
  for (std::size_t k = 0; k < y.size(); ++k) {
    const Vec3 e{y[k][0] - dst[k][0], y[k][1] - dst[k][1], y[k][2] - dst[k][2]};
    double s = 0;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) s += e[a] * W[k][a * 3 + b] * e[b];
    cost += cauchy2 > 0 ? cauchy2 * std::log1p(s / cauchy2) : s;
    if (weight) (*weight)[k] = cauchy2 > 0 ? 1 / (1 + s / cauchy2) : 1;
  }
  return cost;
}

// The inverse of the symmetric positive definite 3x3 c (row-major), by cofactors.
std::array<double, 9> inverse3(const std::array<double, 9> &c) {
  std::array<double, 9> a{};
  a[0] = c[4] * c[8] - c[5] * c[7];
  a[1] = c[2] * c[7] - c[1] * c[8];
  a[2] = c[1] * c[5] - c[2] * c[4];
  a[3] = c[5] * c[6] - c[3] * c[8];
  a[4] = c[0] * c[8] - c[2] * c[6];
  a[5] = c[2] * c[3] - c[0] * c[5];
  a[6] = c[3] * c[7] - c[4] * c[6];
  a[7] = c[1] * c[6] - c[0] * c[7];
  a[8] = c[0] * c[4] - c[1] * c[3];
  const double det = c[0] * a[0] + c[1] * a[3] + c[2] * a[6];
  for (double &v : a) v /= det;
  return a;
}

// y after the similarity near the identity d = (log scale, rotation vector, translation),
// about the centre m: m + e^sigma Exp(omega) (y - m) + tau; as a Similarity in *as.
std::vector<Vec3> moved(const std::vector<Vec3> &y, const Vec3 &m, const std::array<double, 7> &d, Similarity *as) {
  const double theta = std::sqrt(d[1] * d[1] + d[2] * d[2] + d[3] * d[3]);
  const double f = theta > 0 ? std::sin(theta / 2) / theta : 0.5;
  sbacameras::euclidean::rotation_matrix({std::cos(theta / 2), f * d[1], f * d[2], f * d[3]}, as->R.data());
  as->s = std::exp(d[0]);
  for (int a = 0; a < 3; ++a)
    as->t[a] = m[a] + d[4 + a] - as->s * (as->R[a * 3] * m[0] + as->R[a * 3 + 1] * m[1] + as->R[a * 3 + 2] * m[2]);
  std::vector<Vec3> out(y.size());
  for (std::size_t k = 0; k < y.size(); ++k) out[k] = transformed(*as, y[k]);
  return out;
}

// b after a: x -> s_b R_b (s_a R_a x + t_a) + t_b.
Similarity compose(const Similarity &b, const Similarity &a) {
  Similarity c;
  c.s = b.s * a.s;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      c.R[i * 3 + j] = b.R[i * 3] * a.R[j] + b.R[i * 3 + 1] * a.R[3 + j] + b.R[i * 3 + 2] * a.R[6 + j];
  c.t = transformed(b, a.t);
  return c;
}

// Newton's system for a similarity near the identity d = (log scale, rotation vector,
// translation) about the centre of y (moved's), of the priors' cost reweighted by weight: the
// Gauss-Newton matrix H, the second derivatives' part S, the negative gradient g.
struct NewtonSystem {
  Vec3 centre{};
  double spread = 0;  // the mean squared distance of y from centre
  std::array<double, 49> H{}, S{};
  std::array<double, 7> g{};
};

NewtonSystem newton_system(const std::vector<Vec3> &y, const std::vector<Vec3> &dst,
                           const std::vector<std::array<double, 9>> &W, const std::vector<double> &weight) {
  const std::size_t n = y.size();
  NewtonSystem out;
  Vec3 &m = out.centre;
  std::array<double, 49> &H = out.H, &S = out.S;
  std::array<double, 7> &g = out.g;
  for (const Vec3 &v : y)
    for (int a = 0; a < 3; ++a) m[a] += v[a] / static_cast<double>(n);
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3 u{y[k][0] - m[0], y[k][1] - m[1], y[k][2] - m[2]};
    out.spread += (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) / static_cast<double>(n);
    // d y / d(sigma, omega, tau) at the identity: u, -[u]x, I.
    const double J[3][7] = {{u[0], 0, u[2], -u[1], 1, 0, 0},
                            {u[1], -u[2], 0, u[0], 0, 1, 0},
                            {u[2], u[1], -u[0], 0, 0, 0, 1}};
    double WJ[3][7] = {};
    Vec3 v{};  // w W e
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        const double w = weight[k] * W[k][a * 3 + b];
        for (int c = 0; c < 7; ++c) WJ[a][c] += w * J[b][c];
        v[a] += w * (y[k][b] - dst[k][b]);
      }
    for (int c = 0; c < 7; ++c) {
      for (int a = 0; a < 3; ++a) g[c] -= J[a][c] * v[a];
      for (int e = 0; e < 7; ++e)
        for (int a = 0; a < 3; ++a) H[c * 7 + e] += J[a][c] * WJ[a][e];
    }
    // v . d2y: d2y/dsigma2 = u, d2y/dsigma domega_a = e_a x u, d2y/domega_a domega_b the
    // symmetric part of e_a x (e_b x u) = e_b u_a - u delta_ab.
    const double vu = v[0] * u[0] + v[1] * u[1] + v[2] * u[2];
    const Vec3 uv{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    S[0] += vu;
    for (int a = 0; a < 3; ++a) {
      S[1 + a] += uv[a];
      S[(1 + a) * 7] += uv[a];
      for (int b = 0; b < 3; ++b) S[(1 + a) * 7 + 1 + b] += 0.5 * (v[b] * u[a] + v[a] * u[b]) - (a == b ? vu : 0);
    }
  }
  return out;
}

}  // namespace

bool least_cost_similarity(const std::vector<Vec3> &src, const std::vector<Vec3> &dst,
                           const std::vector<const std::array<double, 9> *> &covariances, const std::string &loss,
                           double loss_scale, Similarity *x) {
  const std::size_t n = src.size();
  if (n < 3 || dst.size() != n || covariances.size() != n) return false;
  std::vector<std::array<double, 9>> W(n);
  for (std::size_t k = 0; k < n; ++k) W[k] = inverse3(*covariances[k]);
  const double cauchy2 = loss == "cauchy" ? loss_scale * loss_scale : 0;
  std::vector<Vec3> y(n);
  for (std::size_t k = 0; k < n; ++k) y[k] = transformed(*x, src[k]);
  std::vector<double> weight(n);
  double cost = priors_cost(y, dst, W, cauchy2, &weight);
  bool changed = false;
  int small = 0;  // short steps in a row
  // Newton's method on the reweighted cost (the loss as weights), with the Gauss-Newton
  // matrix where the whole Hessian is not positive definite (far from the minimum): the priors
  // are noisy, so the residuals are not small, and Gauss-Newton alone would creep, even drift,
  // along a direction the priors hold weakly. A step is halved until the cost falls; a short
  // one need only not raise it beyond its rounding, in which its gain drowns.
  for (int iteration = 0; iteration < 100 && small < 3 && std::isfinite(cost); ++iteration) {
    NewtonSystem sys = newton_system(y, dst, W, weight);
    std::array<double, 49> N = sys.H;
    for (int c = 0; c < 49; ++c) N[c] += sys.S[c];
    std::array<double, 7> d = sys.g;
    if (!solve_spd<7>(N, &d)) {
      // A touch of damping keeps a direction the priors do not hold (collinear centres turning
      // about their line) from making the system singular.
      for (int c = 0; c < 7; ++c) sys.H[c * 7 + c] *= 1 + 1e-12;
      d = sys.g;
      if (!solve_spd<7>(sys.H, &d)) break;
    }
    double size = 0;  // the step's largest effect, relative to the points' spread
    for (int c = 0; c < 7; ++c) size = std::max(size, std::fabs(d[c]) / (c < 4 ? 1 : std::sqrt(sys.spread)));
    if (size < 1e-14) break;
    small = size < 1e-6 ? small + 1 : 0;
    bool taken = false;
    for (int half = 0; half < 30 && !taken; ++half) {
      Similarity step;
      std::vector<Vec3> next = moved(y, sys.centre, d, &step);
      const double next_cost = priors_cost(next, dst, W, cauchy2, &weight);
      if (next_cost < cost || (small > 0 && next_cost <= cost * (1 + 1e-14))) {
        taken = true;
        cost = next_cost;
        y = std::move(next);
        *x = compose(step, *x);
        changed = true;
      } else {
        for (double &v : d) v /= 2;
      }
    }
    if (!taken) break;
  }
  return changed;
}

void transform_model(const Similarity &x, Model *model) {
  // X_c = R_c X + t_c with X = R^T (X' - t) / s: s X_c = R_c R^T X' + s t_c - R_c R^T t.
  const auto move_pose = [&x](std::array<double, 4> *q, std::array<double, 3> *t) {
    sbacameras::euclidean::Quaternion qc{(*q)[0], (*q)[1], (*q)[2], (*q)[3]};
    qc = sbacameras::euclidean::normalized_rotation(qc);
    double Rc[9];
    sbacameras::euclidean::rotation_matrix(qc, Rc);
    double M[9];  // R_c R^T
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        M[a * 3 + b] = Rc[a * 3] * x.R[b * 3] + Rc[a * 3 + 1] * x.R[b * 3 + 1] + Rc[a * 3 + 2] * x.R[b * 3 + 2];
    std::array<double, 3> tn;
    for (int a = 0; a < 3; ++a)
      tn[a] = x.s * (*t)[a] - (M[a * 3] * x.t[0] + M[a * 3 + 1] * x.t[1] + M[a * 3 + 2] * x.t[2]);
    *t = tn;
    const sbacameras::euclidean::Quaternion qn = sbacameras::euclidean::quaternion_of(M);
    *q = {qn.w, qn.x, qn.y, qn.z};
  };
  for (Point3D &p : model->points) p.xyz = transformed(x, p.xyz);
  for (Image &im : model->images) move_pose(&im.q, &im.t);
  for (Frame &f : model->frames) move_pose(&f.rig_from_world.q, &f.rig_from_world.t);
  for (Rig &r : model->rigs)
    for (RigSensor &s : r.sensors)
      if (s.has_pose)
        for (double &v : s.sensor_from_rig.t) v *= x.s;
}

std::vector<Vec3> image_centres(const Model &model) {
  const std::vector<Pose> poses = image_poses(model);
  std::vector<Vec3> out;
  out.reserve(poses.size());
  for (const Pose &p : poses) {
    double R[9];
    sbacameras::euclidean::rotation_matrix(
        sbacameras::euclidean::normalized_rotation({p.q[0], p.q[1], p.q[2], p.q[3]}), R);
    out.push_back(sbacameras::camera_centre(R, p.t.data()));
  }
  return out;
}

bool read_point_priors(const std::string &path, const Model &model, std::vector<PointPrior> *out,
                       std::string *error) {
  std::string text;
  return read_whole_file(path, true, &text, error) && parse_point_priors(text, path, model, out, error);
}

bool parse_point_priors(const std::string &text, const std::string &path, const Model &model,
                        std::vector<PointPrior> *out, std::string *error) {
  std::vector<Line> lines;
  lines_of(text, &lines);
  std::unordered_set<std::uint64_t> ids, seen;
  for (const Point3D &p : model.points) ids.insert(p.id);
  out->clear();
  for (const Line &line : lines) {
    const std::string where = at(path, line);
    const std::vector<std::string> &t = line.tokens;
    if (t.size() != 5 && t.size() != 13) {
      *error = where + "expected POINT3D_ID X Y Z SIGMA, or POINT3D_ID X Y Z and the 9 values of a covariance (got " +
               std::to_string(t.size()) + " values)";
      return false;
    }
    PointPrior p;
    p.where = path + ":" + std::to_string(line.number);
    if (!id_value(t[0], "POINT3D_ID", where, std::numeric_limits<std::uint64_t>::max() - 1, &p.point_id, error))
      return false;
    if (!ids.count(p.point_id)) {
      *error = where + "no point has POINT3D_ID " + t[0] + " in the model";
      return false;
    }
    if (!seen.insert(p.point_id).second) {
      *error = where + "point " + t[0] + " has a prior already";
      return false;
    }
    static const char *const kAxes[] = {"X", "Y", "Z"};
    for (int a = 0; a < 3; ++a)
      if (!finite_value(t[1 + static_cast<std::size_t>(a)], kAxes[a], where, &p.position[static_cast<std::size_t>(a)], error))
        return false;
    if (t.size() == 5) {
      double sigma = 0;
      if (!finite_value(t[4], "SIGMA", where, &sigma, error)) return false;
      if (!(sigma > 0) || !(sigma * sigma > 0) || !std::isfinite(sigma * sigma)) {
        *error = where + "SIGMA must be > 0 (and its square finite and not 0), got " + t[4];
        return false;
      }
      p.covariance = {sigma * sigma, 0, 0, 0, sigma * sigma, 0, 0, 0, sigma * sigma};
    } else {
      for (std::size_t k = 0; k < 9; ++k)
        if (!finite_value(t[4 + k], "covariance value " + std::to_string(k + 1), where, &p.covariance[k], error))
          return false;
      if (!symmetric_positive_definite(p.covariance)) {
        *error = where + covariance_message(p.covariance);
        return false;
      }
    }
    out->push_back(p);
  }
  return true;
}

bool read_intrinsic_priors(const std::string &path, const Model &model, std::vector<IntrinsicPrior> *out,
                           std::string *error) {
  std::string text;
  return read_whole_file(path, true, &text, error) && parse_intrinsic_priors(text, path, model, out, error);
}

bool parse_intrinsic_priors(const std::string &text, const std::string &path, const Model &model,
                            std::vector<IntrinsicPrior> *out, std::string *error) {
  std::vector<Line> lines;
  lines_of(text, &lines);
  std::unordered_map<std::uint32_t, int> models;
  for (const Camera &c : model.cameras) models.emplace(c.id, c.model);
  std::unordered_set<std::uint64_t> seen;
  out->clear();
  for (const Line &line : lines) {
    const std::string where = at(path, line);
    const std::vector<std::string> &t = line.tokens;
    if (t.size() != 4) {
      *error = where + "expected CAMERA_ID PARAM MEAN STDDEV (got " + std::to_string(t.size()) + " values)";
      return false;
    }
    IntrinsicPrior p;
    p.where = path + ":" + std::to_string(line.number);
    std::uint64_t id = 0;
    if (!id_value(t[0], "CAMERA_ID", where, 0xffffffffu, &id, error)) return false;
    const auto cam = models.find(static_cast<std::uint32_t>(id));
    if (cam == models.end()) {
      *error = where + "no camera has CAMERA_ID " + t[0] + " in the model";
      return false;
    }
    p.camera_id = static_cast<std::uint32_t>(id);
    const int model_id = cam->second;
    const int nparams = camera_model_params(model_id), focals = sbacameras::colmap_camera::focal_count(model_id);
    const std::string &name = t[1];
    int k = -1;
    if (name == "f" && focals == 1) k = 0;
    else if (name == "fx" && focals == 2) k = 0;
    else if (name == "fy" && focals == 2) k = 1;
    else if (name == "cx" && focals > 0) k = focals;
    else if (name == "cy" && focals > 0) k = focals + 1;
    else {
      std::uint64_t index = 0;
      std::string ignored;
      if (id_value(name, "PARAM", where, 1000, &index, &ignored) && index < static_cast<std::uint64_t>(nparams))
        k = static_cast<int>(index);
    }
    if (k < 0) {
      *error = where + "camera " + t[0] + " (" + camera_model_name(model_id) + ") has no parameter '" +
               TextTokens::printable(name) + "' (its parameters are 0.." + std::to_string(nparams - 1) +
               (focals == 1 ? ", or f, cx, cy)" : focals == 2 ? ", or fx, fy, cx, cy)" : ")");
      return false;
    }
    p.param = k;
    if (!seen.insert(static_cast<std::uint64_t>(p.camera_id) << 8 | static_cast<std::uint64_t>(k)).second) {
      *error = where + "parameter " + std::to_string(k) + " of camera " + t[0] + " has a prior already";
      return false;
    }
    if (!finite_value(t[2], "MEAN", where, &p.mean, error) || !finite_value(t[3], "STDDEV", where, &p.stddev, error))
      return false;
    if (!(p.stddev > 0)) {
      *error = where + "STDDEV must be > 0, got " + t[3];
      return false;
    }
    out->push_back(p);
  }
  return true;
}

}  // namespace sbaformats::colmap

namespace sbaformats::colmap {
namespace {

// Whether x keeps every coordinate of model finite: a bound on |s R X + t| and on each moved
// translation, from the largest magnitudes (priors far from the model at the edge of double's
// range give a similarity that would send it to infinity).
bool keeps_finite(const Similarity &x, const Model &model) {
  double far = 0;  // the largest coordinate of the model
  for (const Point3D &p : model.points)
    for (double v : p.xyz) far = std::max(far, std::fabs(v));
  const auto pose = [&far](const std::array<double, 3> &t) {
    for (double v : t) far = std::max(far, std::fabs(v));
  };
  for (const Image &im : model.images) pose(im.t);
  for (const Frame &f : model.frames) pose(f.rig_from_world.t);
  for (const Rig &r : model.rigs)
    for (const RigSensor &s : r.sensors) pose(s.sensor_from_rig.t);
  double shift = 0;
  for (double v : x.t) shift = std::max(shift, std::fabs(v));
  const double bound = 3 * x.s * far + 3 * shift;  // inf or NaN when out of range
  return bound < std::numeric_limits<double>::max() / 4;
}

// The similarity that moves src onto the priors dst, applied to model; *words: the summary's
// words for it. max_error 0: three times the priors' RMS standard deviation. False, with
// *error, when the similarity would take the model out of double's range.
bool align_model(const std::vector<Vec3> &src, const std::vector<Vec3> &dst,
                 const std::vector<const std::array<double, 9> *> &covariances, double max_error,
                 const std::string &loss, double loss_scale, const std::string &source, Model *model,
                 std::string *words, std::string *error) {
  if (max_error <= 0) {
    double variance = 0;  // the mean over the priors of each axis's variance
    for (const std::array<double, 9> *c : covariances) variance += ((*c)[0] + (*c)[4] + (*c)[8]) / 3;
    max_error = 3 * std::sqrt(variance / static_cast<double>(covariances.size()));
  }
  Similarity x;
  int inliers = 0;
  if (!robust_similarity(src, dst, max_error, &x, &inliers)) {
    *words = "not moved (its positions coincide)";
    return true;
  }
  const Similarity robust = x;
  least_cost_similarity(src, dst, covariances, loss, loss_scale, &x);
  if (!keeps_finite(x, *model)) {
    char text[200];
    std::snprintf(text, sizeof text,
                  ": the model cannot be moved onto these priors: their similarity (scale %.3g) takes it beyond the "
                  "range of double",
                  x.s);
    *error = source + text;
    return false;
  }
  transform_model(x, model);
  char text[160];
  std::snprintf(text, sizeof text, "moved onto them by a similarity of scale %.6g (%d of %zu within %.3g)", robust.s,
                inliers, src.size(), max_error);
  *words = text;
  return true;
}

}  // namespace

bool place_on_priors(std::vector<PosePrior> read, int unknown, const std::string &source,
                     const std::vector<PointPrior> &points, const std::string &points_source,
                     const PosePriorOptions &options, bool align, Model *model, std::vector<PosePrior> *poses,
                     std::string *said, std::string *error) {
  said->clear();
  std::size_t wgs84 = 0;
  for (const PosePrior &p : read) wgs84 += p.system == PriorSystem::Wgs84;
  wgs84_to_enu(&read);
  if (!usable_pose_priors(*model, read, options, poses, error)) return false;
  const std::size_t enough = static_cast<std::size_t>(kMinPosePriors);
  if (!source.empty()) {
    *said = "\nPosition priors: " + std::to_string(poses->size()) + " of the " +
            std::to_string(read.size() + static_cast<std::size_t>(unknown)) + " in " + source +
            " on images that see points";
    if (wgs84 > 0) *said += " (" + std::to_string(wgs84) + " WGS84, taken to metres east, north and up of the first)";
    if (poses->size() < enough) {
      *said += ": fewer than 3, so the model is refined without them, as COLMAP does";
      poses->clear();
    } else if (align) {
      const std::vector<Vec3> centres = image_centres(*model);
      std::unordered_map<std::uint32_t, std::size_t> index;
      for (std::size_t k = 0; k < model->images.size(); ++k) index.emplace(model->images[k].id, k);
      std::vector<Vec3> src, dst;
      std::vector<const std::array<double, 9> *> cov;
      for (const PosePrior &p : *poses) {
        src.push_back(centres[index.at(p.image_id)]);
        dst.push_back(p.position);
        cov.push_back(&p.covariance);
      }
      std::string words;
      if (!align_model(src, dst, cov, options.alignment_max_error, options.loss, options.loss_scale, source, model,
                       &words, error))
        return false;
      *said += ": the model " + words + ", then refined with them";
    }
  }
  if (!points.empty()) {
    *said += "\nPoint priors (ground control points): " + std::to_string(points.size()) + " from " + points_source;
    if (poses->empty() && points.size() >= enough && align) {
      std::unordered_map<std::uint64_t, std::size_t> index;
      for (std::size_t k = 0; k < model->points.size(); ++k) index.emplace(model->points[k].id, k);
      std::vector<Vec3> src, dst;
      std::vector<const std::array<double, 9> *> cov;
      for (const PointPrior &p : points) {
        src.push_back(model->points[index.at(p.point_id)].xyz);
        dst.push_back(p.position);
        cov.push_back(&p.covariance);
      }
      std::string words;
      if (!align_model(src, dst, cov, 0, "", 0, points_source, model, &words, error)) return false;
      *said += ": the model " + words + ", then refined with them";
    }
  }
  return true;
}

}  // namespace sbaformats::colmap
