// Tests for the element rotation extraction (tissue/rotation.hpp): polar_rotation against an
// Eigen JacobiSVD reference with Irving et al.'s sign correction on many random matrices of
// every difficult kind, and the properties of SOFA's edge-frame qr_rotation.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "tissue/rotation.hpp"

namespace stroma {
namespace {

using Mat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

/// Rotation of the polar decomposition computed by the engine.
Mat3 engine_polar(const Mat3& F) {
  Mat3 R;
  polar_rotation(F.data(), R.data());
  return R;
}

/// Reference: R = U Vᵀ from Eigen's JacobiSVD; if det(U Vᵀ) < 0 the column of U belonging to
/// the smallest singular value is negated (Irving et al. 2004), so R ∈ SO(3) maximises tr(RᵀF).
Mat3 reference_polar(const Mat3& F) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(Eigen::Matrix3d(F), Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  const Eigen::Matrix3d V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0) U.col(2) *= -1.0;  // singular values sorted: col 2 smallest
  return Mat3(U * V.transpose());
}

double max_abs(const Mat3& A) { return A.cwiseAbs().maxCoeff(); }

/// Angle of the rotation R1ᵀ R2 (radians).
double rotation_angle_between(const Mat3& R1, const Mat3& R2) {
  const double c = 0.5 * ((R1.transpose() * R2).trace() - 1.0);
  return std::acos(std::clamp(c, -1.0, 1.0));
}

class RandomMatrices {
 public:
  explicit RandomMatrices(uint64_t seed) : rng_(seed) {}
  double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng_); }
  double log_uniform(double a, double b) { return std::exp(uniform(std::log(a), std::log(b))); }
  /// Uniformly distributed rotation (normalised Gaussian quaternion).
  Mat3 rotation() {
    std::normal_distribution<double> n(0.0, 1.0);
    Eigen::Quaterniond q(n(rng_), n(rng_), n(rng_), n(rng_));
    q.normalize();
    return Mat3(q.toRotationMatrix());
  }
  Eigen::Vector3d unit_vector() {
    std::normal_distribution<double> n(0.0, 1.0);
    return Eigen::Vector3d(n(rng_), n(rng_), n(rng_)).normalized();
  }
  Mat3 gaussian() {
    std::normal_distribution<double> n(0.0, 1.0);
    Mat3 A;
    for (int i = 0; i < 9; ++i) A.data()[i] = n(rng_);
    return A;
  }
  /// U · diag(s) · Vᵀ with random rotations U, V.
  Mat3 with_singular_values(double s0, double s1, double s2) {
    return rotation() * Eigen::Vector3d(s0, s1, s2).asDiagonal() * rotation().transpose();
  }

 private:
  std::mt19937_64 rng_;
};

/// Smallest relative gap between the magnitudes of the singular values of F.
double min_relative_gap(const Mat3& F) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd{Eigen::Matrix3d(F)};
  const Eigen::Vector3d s = svd.singularValues();
  return std::min(s(0) - s(1), s(1) - s(2)) / s(0);
}

/// Error statistics of one family of matrices.
struct Stats {
  int count = 0;
  double max_err = 0;     ///< max |R − R_ref| entry
  double max_orth = 0;    ///< max |RᵀR − I| entry
  double max_det = 0;     ///< max |det R − 1|
  void add(const Mat3& R, const Mat3& Rref) {
    max_err = std::max(max_err, max_abs(R - Rref));
    max_orth = std::max(max_orth, max_abs(R.transpose() * R - Mat3::Identity()));
    max_det = std::max(max_det, std::abs(R.determinant() - 1.0));
    ++count;
  }
};

enum Family { kRot, kStretch, kShear, kNearSing, kInverted, kInvNearSing, kRepeated, kGauss, kFamilies };
constexpr const char* kFamilyName[kFamilies] = {
    "pure rotation",        "rotation x sym stretch",  "large shear (gamma 1..10)",
    "near-singular (1e-8)", "inverted (det<0)",        "inverted near-singular",
    "repeated singular values", "gaussian (either sign)"};

struct Sample {
  Family family;
  Mat3 F;
};

/// ≥ 10,000 matrices of every difficult kind (fixed seed).
std::vector<Sample> make_samples() {
  constexpr int kPerFamily = 1500;
  RandomMatrices g(0x5EED'0001ULL);
  std::vector<Sample> out;
  for (int k = 0; k < kPerFamily; ++k) {
    // Pure rotation: the polar factor is F itself.
    out.push_back({kRot, g.rotation()});
    // Rotation × symmetric positive stretch, principal stretches in [0.2, 5].
    {
      const Mat3 P = g.rotation();
      const Eigen::Vector3d s(g.log_uniform(0.2, 5), g.log_uniform(0.2, 5), g.log_uniform(0.2, 5));
      out.push_back({kStretch, g.rotation() * P * s.asDiagonal() * P.transpose()});
    }
    // Large shear: Q (I + γ a bᵀ), a ⟂ b, γ ∈ [1, 10] (stretch ratios up to ~100).
    {
      const Eigen::Vector3d a = g.unit_vector();
      Eigen::Vector3d b = g.unit_vector();
      b = (b - b.dot(a) * a).normalized();
      const double gamma = g.uniform(1.0, 10.0);
      out.push_back({kShear, g.rotation() * (Mat3::Identity() + gamma * a * b.transpose())});
    }
    // Near-singular: one singular value 1e-8, the others in [0.5, 2].
    out.push_back({kNearSing, g.with_singular_values(g.uniform(0.5, 2.0), g.uniform(0.5, 2.0), 1e-8)});
    // Inverted: det < 0 with distinct singular values; the negative sign on a random one
    // (the reference puts it on the smallest). Rejection keeps the smallest well separated.
    for (;;) {
      Eigen::Vector3d s(g.log_uniform(0.2, 3), g.log_uniform(0.2, 3), g.log_uniform(0.2, 3));
      s(static_cast<int>(g.uniform(0, 3)) % 3) *= -1.0;
      const Mat3 F = g.with_singular_values(s(0), s(1), s(2));
      if (min_relative_gap(F) < 1e-2) continue;
      out.push_back({kInverted, F});
      break;
    }
    // Inverted and nearly flat: smallest singular value −1e-8 (pushed just through).
    out.push_back({kInvNearSing, g.with_singular_values(g.uniform(0.5, 2.0), g.uniform(0.5, 2.0), -1e-8)});
    // Repeated singular values: uniform scaling × rotation, and a double singular value
    // (largest or smallest pair).
    {
      out.push_back({kRepeated, g.log_uniform(0.1, 10) * g.rotation()});
      const double a = g.log_uniform(0.2, 5), b = g.log_uniform(0.2, 5);
      out.push_back({kRepeated, g.with_singular_values(a, a, b)});
      out.push_back({kRepeated, g.with_singular_values(b, a, a)});
    }
    // Generic Gaussian matrices of either determinant sign, smallest σ separated.
    for (;;) {
      const Mat3 F = g.gaussian();
      if (min_relative_gap(F) < 1e-3) continue;
      out.push_back({kGauss, F});
      break;
    }
  }
  return out;
}

/// Checks one set of engine results against the reference, per family; returns the max error.
double check_family_stats(const char* what, const std::vector<Sample>& samples,
                          const std::vector<Mat3>& R) {
  Stats st[kFamilies];
  for (size_t i = 0; i < samples.size(); ++i) st[samples[i].family].add(R[i], reference_polar(samples[i].F));
  double worst = 0;
  for (int f = 0; f < kFamilies; ++f) {
    std::printf("  %s %-26s n=%5d  max|R-Rref|=%.3e  max|RtR-I|=%.3e  max|detR-1|=%.3e\n", what,
                kFamilyName[f], st[f].count, st[f].max_err, st[f].max_orth, st[f].max_det);
    EXPECT_LE(st[f].max_err, 1e-10) << what << ", " << kFamilyName[f];
    EXPECT_LE(st[f].max_orth, 1e-12) << what << ", " << kFamilyName[f];
    EXPECT_LE(st[f].max_det, 1e-12) << what << ", " << kFamilyName[f];
    worst = std::max(worst, st[f].max_err);
  }
  return worst;
}

TEST(Rotation, PolarMatchesSvdReferenceOnRandomMatrices) {
  const std::vector<Sample> samples = make_samples();
  ASSERT_GE(samples.size(), 10000u);
  std::vector<Mat3> R(samples.size());
  double max_rot_vs_F = 0;
  for (size_t i = 0; i < samples.size(); ++i) {
    R[i] = engine_polar(samples[i].F);
    if (samples[i].family == kRot) max_rot_vs_F = std::max(max_rot_vs_F, max_abs(R[i] - samples[i].F));
  }
  const double worst = check_family_stats("polar", samples, R);
  std::printf("  polar pure rotation: max|R-F| = %.3e\n", max_rot_vs_F);
  EXPECT_LE(max_rot_vs_F, 1e-12);
  RecordProperty("polar_max_abs_error", std::to_string(worst));
  std::printf("  polar overall max|R-Rref| = %.3e over %zu matrices\n", worst, samples.size());
}

TEST(Rotation, PolarBatchOf8MatchesReferenceAndSingleLane) {
  // The element pass runs polar_rotation_batch (SIMD across elements); every lane must be as
  // accurate as the single-matrix path. Lanes interact only through the path a batch takes
  // (one inverted lane sends the batch through the SVD instead of Newton's iteration), which
  // changes a result by round-off.
  const std::vector<Sample> samples = make_samples();
  constexpr int W = 8;
  std::vector<Mat3> R(samples.size());
  double lane_vs_single = 0;
  for (size_t i0 = 0; i0 < samples.size(); i0 += W) {
    double F[9][W], Rb[9][W];
    for (int l = 0; l < W; ++l) {
      // Pad the last batch by repeating a sample (lanes must be independent anyway).
      const Mat3& Fl = samples[std::min(i0 + l, samples.size() - 1)].F;
      for (int k = 0; k < 9; ++k) F[k][l] = Fl.data()[k];
    }
    polar_rotation_batch<W>(F, Rb);
    for (int l = 0; l < W && i0 + l < samples.size(); ++l) {
      for (int k = 0; k < 9; ++k) R[i0 + l].data()[k] = Rb[k][l];
      lane_vs_single = std::max(lane_vs_single, max_abs(R[i0 + l] - engine_polar(samples[i0 + l].F)));
    }
  }
  check_family_stats("batch8", samples, R);
  std::printf("  batch8 vs single-lane: max diff %.3e\n", lane_vs_single);
  EXPECT_LE(lane_vs_single, 5e-14);
}

TEST(Rotation, PolarOfInvertedMatrixIsProperRotationNearestF) {
  // F = diag(2, 1, −0.5): Irving's R puts the reflection on the smallest singular value, so
  // R = I (not the improper diag(1, 1, −1)), and tr(RᵀF) = 2 + 1 − 0.5 is the maximum over SO(3).
  RandomMatrices g(0x5EED'0002ULL);
  for (int k = 0; k < 100; ++k) {
    const Mat3 U = g.rotation(), V = g.rotation();
    const Mat3 F = U * Eigen::Vector3d(2.0, 1.0, -0.5).asDiagonal() * V.transpose();
    const Mat3 R = engine_polar(F);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    EXPECT_LE(max_abs(R - U * V.transpose()), 1e-12);
    EXPECT_NEAR((R.transpose() * F).trace(), 2.5, 1e-12);
    // No other rotation does better: compare with random rotations.
    for (int j = 0; j < 20; ++j) EXPECT_LE((g.rotation().transpose() * F).trace(), 2.5 + 1e-12);
  }
}

TEST(Rotation, PolarOfSimpleShearHasAnalyticAngle) {
  // Simple shear F = I + γ e_x e_yᵀ: the polar rotation is about z by θ = atan(γ/2).
  for (double gamma : {0.1, 1.0, 3.0}) {
    Mat3 F = Mat3::Identity();
    F(0, 1) = gamma;
    const Mat3 R = engine_polar(F);
    const double th = std::atan(gamma / 2.0);
    Mat3 Rz;
    Rz << std::cos(th), std::sin(th), 0, -std::sin(th), std::cos(th), 0, 0, 0, 1;
    EXPECT_LE(max_abs(R - Rz), 1e-12) << "gamma = " << gamma;
  }
}

TEST(Rotation, QrRecoversRigidRotationOfRestEdges) {
  RandomMatrices g(0x5EED'0003ULL);
  double worst = 0;
  for (int k = 0; k < 2000; ++k) {
    // Random, well-shaped rest edges (not parallel).
    Eigen::Vector3d e1 = g.unit_vector() * g.uniform(0.5, 2.0);
    Eigen::Vector3d e2;
    do e2 = g.unit_vector() * g.uniform(0.5, 2.0);
    while (e1.normalized().cross(e2.normalized()).norm() < 0.2);
    double rest_frame[9];
    edge_frame(e1.data(), e2.data(), rest_frame);
    const Mat3 Q = g.rotation();
    const Eigen::Vector3d c1 = Q * e1, c2 = Q * e2;
    Mat3 R;
    qr_rotation(rest_frame, c1.data(), c2.data(), R.data());
    worst = std::max(worst, max_abs(R - Q));
  }
  std::printf("  qr rigid rotation: max|R-Q| = %.3e\n", worst);
  EXPECT_LE(worst, 1e-13);
}

TEST(Rotation, QrIsNotThePolarRotationUnderLargeShear) {
  // Documents that qr_rotation is a different rotation: under a shear that keeps the first edge
  // and the (e1, e2) plane fixed, QR returns the identity, while the polar rotation of
  // F = I + γ e_x e_yᵀ turns by atan(γ/2) (0.46 rad at γ = 1).
  const double e1[3] = {1, 0, 0}, e2[3] = {0, 1, 0};
  double rest_frame[9];
  edge_frame(e1, e2, rest_frame);
  for (double gamma : {1.0, 2.0}) {
    Mat3 F = Mat3::Identity();
    F(0, 1) = gamma;
    const Eigen::Vector3d c1 = F * Eigen::Vector3d(1, 0, 0), c2 = F * Eigen::Vector3d(0, 1, 0);
    Mat3 Rqr;
    qr_rotation(rest_frame, c1.data(), c2.data(), Rqr.data());
    const Mat3 Rpolar = engine_polar(F);
    const double angle = rotation_angle_between(Rqr, Rpolar);
    std::printf("  gamma=%.1f: angle(QR, polar) = %.4f rad\n", gamma, angle);
    EXPECT_GT(angle, 0.1) << "gamma = " << gamma;
    EXPECT_NEAR(angle, std::atan(gamma / 2.0), 1e-12);
    EXPECT_NEAR(Rqr.determinant(), 1.0, 1e-12);
  }
  // The same holds for a rotated copy of the configuration (both methods are frame-covariant).
  RandomMatrices g(0x5EED'0004ULL);
  const Mat3 Q = g.rotation();
  Mat3 F = Mat3::Identity();
  F(0, 1) = 1.0;
  const Mat3 QF = Q * F;
  const Eigen::Vector3d c1 = QF * Eigen::Vector3d(1, 0, 0), c2 = QF * Eigen::Vector3d(0, 1, 0);
  Mat3 Rqr;
  qr_rotation(rest_frame, c1.data(), c2.data(), Rqr.data());
  EXPECT_GT(rotation_angle_between(Rqr, engine_polar(QF)), 0.1);
}

// The batched path: Newton's iteration takes a batch whose elements all have det F > 0 and
// agrees with the SVD path to round-off; one inverted or flat element sends the batch to the
// SVD (Newton reports it cannot), and the result is Irving's rotation for every lane.
TEST(Rotation, NewtonBatchMatchesTheSvdBatchAndLeavesInvertedBatchesToIt) {
  constexpr int W = 16;
  RandomMatrices g(0x5EED'0016ULL);
  auto fill = [&](double (&F)[9][W], int special, double s3) {
    for (int l = 0; l < W; ++l) {
      const double a = g.log_uniform(0.3, 3), b = g.log_uniform(0.3, 3), c = l == special ? s3 : g.log_uniform(0.3, 3);
      const Mat3 Fl = g.with_singular_values(a, b, c);  // proper rotations: det F has c's sign
      for (int k = 0; k < 9; ++k) F[k][l] = Fl.data()[k];
    }
  };
  auto max_diff = [](const double (&A)[9][W], const double (&B)[9][W]) {
    double d = 0;
    for (int k = 0; k < 9; ++k)
      for (int l = 0; l < W; ++l) d = std::max(d, std::abs(A[k][l] - B[k][l]));
    return d;
  };
  double F[9][W], Rn[9][W], Rs[9][W], Rb[9][W];
  for (int trial = 0; trial < 50; ++trial) {
    fill(F, -1, 0);
    ASSERT_TRUE(polar_rotation_newton_batch<W>(F, Rn)) << "trial " << trial;
    polar_rotation_svd_batch<W>(F, Rs);
    EXPECT_LE(max_diff(Rn, Rs), 1e-13) << "trial " << trial;
    polar_rotation_batch<W>(F, Rb);
    EXPECT_EQ(max_diff(Rb, Rn), 0.0) << "the batch did not take Newton's path";
  }
  for (const double s3 : {-0.5, -1e-6, 0.0}) {
    fill(F, 5, s3);
    EXPECT_FALSE(polar_rotation_newton_batch<W>(F, Rn)) << "sigma3 " << s3;
    polar_rotation_batch<W>(F, Rb);
    polar_rotation_svd_batch<W>(F, Rs);
    EXPECT_EQ(max_diff(Rb, Rs), 0.0) << "sigma3 " << s3;
    for (int l = 0; l < W; ++l) {
      Mat3 R, Fl;
      for (int k = 0; k < 9; ++k) {
        R.data()[k] = Rb[k][l];
        Fl.data()[k] = F[k][l];
      }
      EXPECT_LE((R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff(), 1e-12);
      EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
      EXPECT_LE(max_abs(R - reference_polar(Fl)), 1e-10) << "lane " << l << " sigma3 " << s3;
    }
  }
}

}  // namespace
}  // namespace stroma
