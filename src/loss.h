// Robust losses rho(s) of a projection's squared (covariance-weighted) residual norm s, with
// scale c: residuals much larger than c count less than quadratically. The solver uses them
// by iteratively reweighted least squares (see lm_core.cpp).
#ifndef SBA_SRC_LOSS_H
#define SBA_SRC_LOSS_H

#include <cmath>
#include <string>

namespace sba {

enum class LossKind { None, Huber, Cauchy, SoftL1, Tukey };

class Loss {
 public:
  Loss() = default;
  Loss(LossKind kind, double scale) : kind_(kind), c2_(scale * scale) {}

  LossKind kind() const { return kind_; }
  bool robust() const { return kind_ != LossKind::None; }
  // A squared residual beyond this is where the loss stops being quadratic: an outlier.
  double scale2() const { return c2_; }

  // rho(s), with rho(s) = s for small s.
  double rho(double s) const {
    switch (kind_) {
      case LossKind::None: return s;
      case LossKind::Huber: return s <= c2_ ? s : 2.0 * std::sqrt(c2_ * s) - c2_;
      case LossKind::Cauchy: return c2_ * std::log1p(s / c2_);
      case LossKind::SoftL1: return 2.0 * c2_ * (std::sqrt(1.0 + s / c2_) - 1.0);
      case LossKind::Tukey: {
        if (s >= c2_) return c2_ / 3.0;
        const double t = 1.0 - s / c2_;
        return c2_ / 3.0 * (1.0 - t * t * t);
      }
    }
    return s;
  }
  // rho'(s), in [0, 1].
  double weight(double s) const {
    switch (kind_) {
      case LossKind::None: return 1.0;
      case LossKind::Huber: return s <= c2_ ? 1.0 : std::sqrt(c2_ / s);
      case LossKind::Cauchy: return 1.0 / (1.0 + s / c2_);
      case LossKind::SoftL1: return 1.0 / std::sqrt(1.0 + s / c2_);
      case LossKind::Tukey: {
        if (s >= c2_) return 0.0;
        const double t = 1.0 - s / c2_;
        return t * t;
      }
    }
    return 1.0;
  }

 private:
  LossKind kind_ = LossKind::None;
  double c2_ = 1.0;
};

// "none", "huber", "cauchy", "soft-l1", "tukey"; false for an unknown name.
inline bool loss_from_name(const std::string &name, LossKind *out) {
  static const struct {
    const char *name;
    LossKind kind;
  } kNames[] = {{"none", LossKind::None},
                {"huber", LossKind::Huber},
                {"cauchy", LossKind::Cauchy},
                {"soft-l1", LossKind::SoftL1},
                {"tukey", LossKind::Tukey}};
  for (const auto &n : kNames)
    if (name == n.name) {
      *out = n.kind;
      return true;
    }
  return false;
}

}  // namespace sba

#endif
