#include "core/flicker.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/error.h"
#include "core/parallel.h"

namespace hmc {
namespace {

// T frames of V random points moving randomly (the truth motion must not
// matter: flicker only sees the error).
std::vector<MatX3d> RandomTruth(std::mt19937* rng, int num_frames,
                                int num_vertices) {
  std::normal_distribution<double> n(0.0, 20.0);
  std::vector<MatX3d> truth(num_frames, MatX3d(num_vertices, 3));
  for (MatX3d& frame : truth) {
    for (Eigen::Index i = 0; i < frame.size(); ++i) frame.data()[i] = n(*rng);
  }
  return truth;
}

// Error e_v(t) = a_v t^2 + b_v t + c_v: its second difference is 2 a_v for
// every t, so flicker = mean over counted vertices of 2 |a_v|.
struct QuadraticError {
  MatX3d a, b, c;  // V x 3 each (mm/frame^2, mm/frame, mm)

  QuadraticError(std::mt19937* rng, int num_vertices) {
    std::normal_distribution<double> n(0.0, 1.0);
    a.resize(num_vertices, 3);
    b.resize(num_vertices, 3);
    c.resize(num_vertices, 3);
    for (Eigen::Index i = 0; i < a.size(); ++i) {
      a.data()[i] = 0.3 * n(*rng);
      b.data()[i] = 2.0 * n(*rng);
      c.data()[i] = 5.0 * n(*rng);
    }
  }
  MatX3d At(int t) const { return a * double(t) * t + b * double(t) + c; }
  double Flicker(const std::vector<char>& mask) const {
    double sum = 0;
    int count = 0;
    for (Eigen::Index v = 0; v < a.rows(); ++v) {
      if (!mask.empty() && !mask[v]) continue;
      sum += 2.0 * a.row(v).norm();
      ++count;
    }
    return count > 0 ? sum / count : 0.0;
  }
};

std::vector<MatX3d> AddError(const std::vector<MatX3d>& truth,
                             const QuadraticError& error) {
  std::vector<MatX3d> recon = truth;
  for (size_t t = 0; t < recon.size(); ++t) recon[t] += error.At(int(t));
  return recon;
}

class FlickerSeeded : public ::testing::TestWithParam<int> {};

TEST_P(FlickerSeeded, ZeroForConstantError) {
  std::mt19937 rng(GetParam());
  const std::vector<MatX3d> truth = RandomTruth(&rng, 9, 40);
  std::normal_distribution<double> n(0.0, 3.0);
  MatX3d offset(40, 3);
  for (Eigen::Index i = 0; i < offset.size(); ++i) offset.data()[i] = n(rng);
  std::vector<MatX3d> recon = truth;
  for (MatX3d& frame : recon) frame += offset;
  const FlickerStats s = ComputeFlicker(truth, recon, {}, {});
  EXPECT_EQ(s.frames_used, 7);
  EXPECT_NEAR(s.mean, 0.0, 1e-12);
  // Identical sequences: exactly zero.
  EXPECT_EQ(ComputeFlicker(truth, truth, {}, {}).mean, 0.0);
}

TEST_P(FlickerSeeded, QuadraticErrorGivesAnalyticValue) {
  std::mt19937 rng(GetParam());
  const int num_frames = 6 + GetParam() % 5;
  const std::vector<MatX3d> truth = RandomTruth(&rng, num_frames, 30);
  const QuadraticError error(&rng, 30);
  const FlickerStats s = ComputeFlicker(truth, AddError(truth, error), {}, {});
  EXPECT_EQ(s.frames_used, num_frames - 2);
  EXPECT_NEAR(s.mean, error.Flicker({}), 1e-9);
  EXPECT_GT(s.mean, 0.0);
}

TEST_P(FlickerSeeded, IndependentOfConstantRigidOffset) {
  std::mt19937 rng(GetParam());
  const std::vector<MatX3d> truth = RandomTruth(&rng, 8, 25);
  const QuadraticError error(&rng, 25);
  const std::vector<MatX3d> recon = AddError(truth, error);
  const double base = ComputeFlicker(truth, recon, {}, {}).mean;

  // A constant translation of the reconstruction.
  std::normal_distribution<double> n(0.0, 10.0);
  const Eigen::RowVector3d shift(n(rng), n(rng), n(rng));
  std::vector<MatX3d> shifted = recon;
  for (MatX3d& frame : shifted) frame.rowwise() += shift;
  EXPECT_NEAR(ComputeFlicker(truth, shifted, {}, {}).mean, base, 1e-9);

  // The same rigid motion applied to truth and reconstruction.
  const Eigen::Quaterniond q =
      Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
  const Mat3 rotation = q.toRotationMatrix();
  std::vector<MatX3d> truth_moved = truth, recon_moved = recon;
  for (size_t t = 0; t < truth.size(); ++t) {
    truth_moved[t] = (truth[t] * rotation.transpose()).rowwise() + shift;
    recon_moved[t] = (recon[t] * rotation.transpose()).rowwise() + shift;
  }
  EXPECT_NEAR(ComputeFlicker(truth_moved, recon_moved, {}, {}).mean, base,
              1e-9);
}

TEST_P(FlickerSeeded, BadFramesBreakTriplets) {
  std::mt19937 rng(GetParam());
  const int num_frames = 12;
  const std::vector<MatX3d> truth = RandomTruth(&rng, num_frames, 20);
  const QuadraticError error(&rng, 20);
  std::vector<MatX3d> recon = AddError(truth, error);
  // A spike at one frame: with the frame flagged it must not count at all.
  std::uniform_int_distribution<int> pick(0, num_frames - 1);
  const int spike = pick(rng);
  recon[spike].array() += 100.0;
  std::vector<char> bad(num_frames, 0);
  bad[spike] = 1;
  const FlickerStats flagged = ComputeFlicker(truth, recon, {}, bad);
  // Centre frames 1..T-2 minus those whose triplet contains the spike.
  int expected_used = 0;
  for (int t = 1; t + 1 < num_frames; ++t) {
    if (std::abs(t - spike) > 1) ++expected_used;
  }
  EXPECT_EQ(flagged.frames_used, expected_used);
  EXPECT_NEAR(flagged.mean, error.Flicker({}), 1e-9);
  // Unflagged, the spike shows.
  EXPECT_GT(ComputeFlicker(truth, recon, {}, {}).mean,
            error.Flicker({}) + 1.0);

  // Every other frame bad: no complete triplet remains.
  std::vector<char> alternate(num_frames, 0);
  for (int t = 0; t < num_frames; t += 2) alternate[t] = 1;
  const FlickerStats none = ComputeFlicker(truth, recon, {}, alternate);
  EXPECT_EQ(none.frames_used, 0);
  EXPECT_EQ(none.mean, 0.0);
}

TEST_P(FlickerSeeded, MaskRespected) {
  std::mt19937 rng(GetParam());
  const int num_vertices = 50;
  const std::vector<MatX3d> truth = RandomTruth(&rng, 7, num_vertices);
  const QuadraticError error(&rng, num_vertices);
  std::vector<MatX3d> recon = AddError(truth, error);
  std::bernoulli_distribution in_mask(0.5);
  std::vector<char> mask(num_vertices);
  for (char& m : mask) m = in_mask(rng);
  mask[0] = 1;  // at least one counted vertex
  mask[1] = 0;  // at least one left out
  // Wild frame-to-frame noise on the vertices outside the mask only.
  std::normal_distribution<double> n(0.0, 50.0);
  for (MatX3d& frame : recon) {
    for (int v = 0; v < num_vertices; ++v) {
      if (!mask[v]) frame.row(v) += Eigen::RowVector3d(n(rng), n(rng), n(rng));
    }
  }
  EXPECT_NEAR(ComputeFlicker(truth, recon, mask, {}).mean,
              error.Flicker(mask), 1e-9);
  EXPECT_GT(ComputeFlicker(truth, recon, {}, {}).mean,
            error.Flicker(mask) + 1.0);
}

TEST_P(FlickerSeeded, SameResultForAnyThreadCount) {
  std::mt19937 rng(GetParam());
  const std::vector<MatX3d> truth = RandomTruth(&rng, 30, 200);
  std::vector<MatX3d> recon = RandomTruth(&rng, 30, 200);
  double one_thread = 0;
  {
    ThreadLimit limit(1);
    one_thread = ComputeFlicker(truth, recon, {}, {}).mean;
  }
  EXPECT_EQ(ComputeFlicker(truth, recon, {}, {}).mean, one_thread);
}

INSTANTIATE_TEST_SUITE_P(Seeds, FlickerSeeded, ::testing::Values(1, 2, 7, 42));

TEST(Flicker, TooFewFramesGiveNothing) {
  std::mt19937 rng(3);
  for (int num_frames = 0; num_frames < 3; ++num_frames) {
    const std::vector<MatX3d> truth = RandomTruth(&rng, num_frames, 5);
    const std::vector<MatX3d> recon = RandomTruth(&rng, num_frames, 5);
    const FlickerStats s = ComputeFlicker(truth, recon, {}, {});
    EXPECT_EQ(s.frames_used, 0);
    EXPECT_EQ(s.mean, 0.0);
  }
}

TEST(Flicker, MismatchedSizesAreInputErrors) {
  std::mt19937 rng(4);
  const std::vector<MatX3d> truth = RandomTruth(&rng, 5, 6);
  EXPECT_THROW(ComputeFlicker(truth, RandomTruth(&rng, 4, 6), {}, {}),
               InputError);
  EXPECT_THROW(ComputeFlicker(truth, RandomTruth(&rng, 5, 7), {}, {}),
               InputError);
  EXPECT_THROW(ComputeFlicker(truth, truth, std::vector<char>(5, 1), {}),
               InputError);
  EXPECT_THROW(ComputeFlicker(truth, truth, {}, std::vector<char>(4, 0)),
               InputError);
}

}  // namespace
}  // namespace hmc
