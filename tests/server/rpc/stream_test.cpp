// StreamSamples through the real service: the whole motion arrives in order with its exact
// count and end time; samples are consistent (on the path, unit orientation, velocity that
// integrates to the positions); a client that cancels or whose deadline passes ends the
// stream with CANCELLED / DEADLINE_EXCEEDED, also while a real-time stream is waiting.
#include <cmath>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <gmock/gmock.h>

#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

class StreamTest : public ServerTest {};

Eigen::Vector3d vec(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

TEST_F(StreamTest, TheWholeMotionInOrder) {
  grpc::Status status;
  const auto samples = stream_all(demo_request('a'), status);  // 10 s at 100 Hz
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(samples.size(), 1001u);
  for (std::size_t k = 0; k < samples.size(); ++k) EXPECT_DOUBLE_EQ(samples[k].t(), k == 1000 ? 10.0 : k * 0.01);
  EXPECT_DOUBLE_EQ(samples.back().u(), 3.0);
  EXPECT_EQ(samples.front().speed(), 0.0);
  EXPECT_NEAR(samples.back().speed(), 0.0, 1e-12);
}

// Positions integrate the velocities (trapezoidal rule, error O(dt^2 |jerk|)), and the
// orientation is a unit quaternion that turns little between samples.
TEST_F(StreamTest, SamplesAreConsistent) {
  auto request = demo_request('c');
  request.mutable_motion()->set_cycle_rate_hz(1000.0);
  for (auto& frame : *request.mutable_path()->mutable_frames()) {
    frame.set_orientation_mode(v1::ORIENTATION_MODE_PARALLEL_TRANSPORT);  // tool z along the tangent
  }
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(samples.size(), 10001u);
  for (std::size_t k = 0; k + 1 < samples.size(); ++k) {
    const auto& a = samples[k];
    const auto& b = samples[k + 1];
    const double dt = b.t() - a.t();
    const Eigen::Vector3d predicted = vec(a.position()) + 0.5 * dt * (vec(a.velocity()) + vec(b.velocity()));
    EXPECT_LT((predicted - vec(b.position())).norm(), 1e-6) << "at t = " << a.t();
    const Eigen::Quaterniond qa(a.orientation().w(), a.orientation().x(), a.orientation().y(), a.orientation().z());
    const Eigen::Quaterniond qb(b.orientation().w(), b.orientation().x(), b.orientation().y(), b.orientation().z());
    EXPECT_NEAR(qa.norm(), 1.0, 1e-12);
    EXPECT_GT(std::abs(qa.dot(qb)), std::cos(0.05)) << "orientation jumps at t = " << a.t();
  }
}

TEST_F(StreamTest, ClientCancelsMidStream) {
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(3600.0);  // 360,001 samples
  request.set_samples_per_batch(100);
  auto context = ServerTest::context();
  auto reader = stub_->StreamSamples(context.get(), request);
  v1::SampleBatch batch;
  std::size_t received = 0;
  while (received < 1000 && reader->Read(&batch)) received += static_cast<std::size_t>(batch.samples_size());
  context->TryCancel();
  while (reader->Read(&batch)) received += static_cast<std::size_t>(batch.samples_size());
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_LT(received, 360001u);
}

TEST_F(StreamTest, DeadlinePassesWhileARealTimeStreamWaits) {
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(3600.0);
  request.set_pacing(v1::STREAM_PACING_REAL_TIME);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(300));
  auto reader = stub_->StreamSamples(&context, request);
  v1::SampleBatch batch;
  std::size_t received = 0;
  while (reader->Read(&batch)) received += static_cast<std::size_t>(batch.samples_size());
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
  EXPECT_GE(received, 1u);
  EXPECT_LT(received, 360001u);
}

TEST_F(StreamTest, UnknownPacingIsNamed) {
  auto request = demo_request('a');
  request.set_pacing(static_cast<v1::StreamPacing>(7));
  grpc::Status status;
  (void)stream_all(request, status);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), ::testing::HasSubstr("pacing"));
}

}  // namespace
}  // namespace geotraj::testing
