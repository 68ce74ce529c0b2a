/* SPDX-License-Identifier: BSD-3-Clause */
// Robust losses rho(s) of a projection's squared (covariance-weighted) residual norm s, with
// scale c: residuals much larger than c count less than quadratically. The solver uses them
// by iteratively reweighted least squares (see lm_core.cpp).
#ifndef SBA_SRC_LOSS_H
#define SBA_SRC_LOSS_H

#include <cmath>
#include <string>

#include "named.h"

namespace sba {

enum class LossKind { None, Huber, Cauchy, SoftL1, Tukey };

// The scales a loss accepts: scale^2 and 1/scale^2 are then finite normal numbers, which is
// what the formulas below divide and multiply by (the drivers refuse anything else).
constexpr double kMinLossScale = 0x1p-511, kMaxLossScale = 0x1p511;

class Loss {
 public:
  Loss() = default;
  // Usable for a scale in [kMinLossScale, kMaxLossScale] (Options::is_valid).
  Loss(LossKind kind, double scale) : kind_(kind), c_(scale), c2_(scale * scale) {}

  LossKind kind() const { return kind_; }
  bool robust() const { return kind_ != LossKind::None; }
  double scale() const { return c_; }
  // A squared residual beyond this is where the loss stops being quadratic: an outlier.
  double scale2() const { return c2_; }

  // rho(s), with rho(s) = s for small s. Written so that no intermediate overflows for any
  // finite s, and without the cancellation of 1 + s/c^2 - 1 when s is far below c^2 (a
  // huge scale must behave as least squares, not as a zero cost).
  double rho(double s) const {
    switch (kind_) {
      case LossKind::None: return s;
      case LossKind::Huber: return s <= c2_ ? s : 2.0 * c_ * std::sqrt(s) - c2_;
      case LossKind::Cauchy: {
        const double u = s / c2_;  // log1p(u), or log(s / c^2) where u overflows
        return c2_ * (std::isfinite(u) ? std::log1p(u) : std::log(s) - std::log(c2_));
      }
      case LossKind::SoftL1: {
        // 2 c^2 (sqrt(1 + s/c^2) - 1) = 2 s c / (hypot(c, sqrt(s)) + c)
        return 2.0 * s * c_ / (std::hypot(c_, std::sqrt(s)) + c_);
      }
      case LossKind::Tukey: {
        if (s >= c2_) return c2_ / 3.0;
        // c^2/3 (1 - t^3) with t = 1 - s/c^2, and 1 - t^3 = (1 - t)(1 + t + t^2)
        const double t = 1.0 - s / c2_;
        return s / 3.0 * (1.0 + t + t * t);
      }
    }
    return s;
  }
  // rho'(s), in [0, 1].
  double weight(double s) const {
    switch (kind_) {
      case LossKind::None: return 1.0;
      case LossKind::Huber: return s <= c2_ ? 1.0 : c_ / std::sqrt(s);
      case LossKind::Cauchy: return c2_ / (c2_ + s);
      case LossKind::SoftL1: return c_ / std::hypot(c_, std::sqrt(s));
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
  double c_ = 1.0, c2_ = 1.0;
};

struct NamedLoss {
  const char *name;
  LossKind value;
};
constexpr NamedLoss kLosses[] = {{"none", LossKind::None},
                                 {"huber", LossKind::Huber},
                                 {"cauchy", LossKind::Cauchy},
                                 {"soft-l1", LossKind::SoftL1},
                                 {"tukey", LossKind::Tukey}};

// false for an unknown name.
inline bool loss_from_name(const std::string &name, LossKind *out) {
  return value_of(kLosses, name, out);
}

// The names above, space-separated.
inline constexpr auto kLossNames = joined_names<joined_length(kLosses)>(kLosses);
inline const char *loss_names() { return kLossNames.text; }

}  // namespace sba

#endif
