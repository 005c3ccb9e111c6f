// Sampling any trajectory with the tool's full state and the joints. See trajectory.hpp.
#include "core/planning/trajectory.hpp"

#include "core/robot/dynamics.hpp"

namespace geotraj::core {
namespace {

template <class... F>
struct Overloaded : F... {
  using F::operator()...;
};
template <class... F>
Overloaded(F...) -> Overloaded<F...>;

}  // namespace

std::size_t sample_count(const StepMotion& step) {
  return std::visit(Overloaded{[](const PathMotion& m) { return m.timing.sample_count; },
                               [](const JointMovePlan& m) { return m.sample_count; },
                               [](const LinearMovePlan& m) { return m.sample_count; },
                               [](const JointPathPlan& m) { return m.sample_count; }},
                    step);
}

double duration(const StepMotion& step) {
  return std::visit(Overloaded{[](const PathMotion& m) { return m.timing.duration_s; },
                               [](const JointMovePlan& m) { return m.duration_s; },
                               [](const LinearMovePlan& m) { return m.duration_s; },
                               [](const JointPathPlan& m) { return m.duration_s; }},
                    step);
}

std::size_t sample_count(const Trajectory& trajectory) {
  return std::visit(Overloaded{[](const PathMotion& m) { return m.timing.sample_count; },
                               [](const JointMovePlan& m) { return m.sample_count; },
                               [](const LinearMovePlan& m) { return m.sample_count; },
                               [](const SequenceMotion& m) { return m.sample_count; },
                               [](const JointPathPlan& m) { return m.sample_count; }},
                    trajectory);
}

double duration(const Trajectory& trajectory) {
  return std::visit(Overloaded{[](const PathMotion& m) { return m.timing.duration_s; },
                               [](const JointMovePlan& m) { return m.duration_s; },
                               [](const LinearMovePlan& m) { return m.duration_s; },
                               [](const SequenceMotion& m) { return m.duration_s; },
                               [](const JointPathPlan& m) { return m.duration_s; }},
                    trajectory);
}

const MotionSpec& motion_spec(const StepMotion& step) {
  return std::visit(Overloaded{[](const PathMotion& m) -> const MotionSpec& { return m.timing.spec; },
                               [](const JointMovePlan& m) -> const MotionSpec& { return m.spec; },
                               [](const LinearMovePlan& m) -> const MotionSpec& { return m.spec; },
                               [](const JointPathPlan& m) -> const MotionSpec& { return m.spec; }},
                    step);
}

const MotionSpec& motion_spec(const Trajectory& trajectory) {
  return std::visit(Overloaded{[](const PathMotion& m) -> const MotionSpec& { return m.timing.spec; },
                               [](const JointMovePlan& m) -> const MotionSpec& { return m.spec; },
                               [](const LinearMovePlan& m) -> const MotionSpec& { return m.spec; },
                               [](const SequenceMotion& m) -> const MotionSpec& { return motion_spec(m.steps.front()); },
                               [](const JointPathPlan& m) -> const MotionSpec& { return m.spec; }},
                    trajectory);
}

SequenceMotion make_sequence(std::vector<StepMotion> steps, double rate_hz) {
  SequenceMotion out;
  out.steps = std::move(steps);
  std::size_t first = 0;
  out.segment_steps.resize(out.steps.size());
  for (std::size_t k = 0; k < out.steps.size(); ++k) {
    out.step_index.push_back(k);
    out.first_samples.push_back(first);
    out.start_times.push_back(static_cast<double>(first) / rate_hz);
    const std::size_t n = sample_count(out.steps[k]);
    if (k + 1 < out.steps.size()) {
      first += n - 1;  // its last sample (the rest at its end) is the next step's first
    } else {
      out.sample_count = first + n;
      out.duration_s = out.start_times.back() + duration(out.steps[k]);
    }
  }
  return out;
}

StepSampler::StepSampler(StepRef step, const RobotModel* robot, const JointVector& seed, const IkOptions& options)
    : step_(step), dynamics_(robot != nullptr && has_dynamics(*robot) ? robot : nullptr) {
  std::visit(Overloaded{[&](const PathMotion* m) { path_sampler_.emplace(m->path, m->timing); },
                        [&](const JointMovePlan* m) { joint_sampler_.emplace(*m); },
                        [&](const LinearMovePlan* m) { linear_sampler_.emplace(*m); },
                        [&](const JointPathPlan* m) { joint_path_sampler_.emplace(*m); }},
             step);
  // Joint moves and joint paths carry their joints; the others need the IK at every sample.
  if (robot != nullptr && !joint_sampler_ && !joint_path_sampler_) tracker_.emplace(*robot, seed, options);
  const auto follow = [&](const std::shared_ptr<const JointReference>& joints) {
    if (joints && joints->samples().front().size() == static_cast<Eigen::Index>(robot->dof()))
      tracker_->set_reference(joints.get());
  };
  if (tracker_ && path_sampler_) {
    const PathMotion& m = *std::get<const PathMotion*>(step_);
    path_between_.emplace(m.path, m.orientation, *path_sampler_);
    follow(m.joints);
  }
  if (tracker_ && linear_sampler_) follow(std::get<const LinearMovePlan*>(step_)->joints);
}

namespace {

// The tool's Cartesian state of a move sample.
CartesianState move_state(const MoveSample& ms) {
  CartesianState x;
  x.t = ms.t;
  x.X_WT.linear() = ms.q_WT.toRotationMatrix();
  x.X_WT.translation() = ms.p_W;
  x.v_WT = ms.v_W;
  x.a_WT = ms.a_W;
  x.omega_WT = ms.omega_W;
  x.alpha_WT = ms.alpha_W;
  return x;
}

}  // namespace

bool StepSampler::next(TrajectorySample& out) {
  if (path_sampler_) {
    if (!path_sampler_->next(motion_sample_)) return false;
  } else if (!(joint_sampler_        ? joint_sampler_->next(move_sample_)
                : joint_path_sampler_ ? joint_path_sampler_->next(move_sample_)
                                      : linear_sampler_->next(move_sample_))) {
    return false;
  }
  finish(out);
  return true;
}

void StepSampler::at(double t, TrajectorySample& out) {
  if (path_sampler_) {
    path_sampler_->at(t, motion_sample_);
  } else if (joint_sampler_) {
    joint_sampler_->at(t, move_sample_);
  } else if (joint_path_sampler_) {
    joint_path_sampler_->at(t, move_sample_);
  } else {
    linear_sampler_->at(t, move_sample_);
  }
  finish(out);
}

void StepSampler::finish(TrajectorySample& out) {
  CartesianState& x = out.tool;
  if (path_sampler_) {
    const PathMotion& m = *std::get<const PathMotion*>(step_);
    const MotionSample& ms = motion_sample_;
    x = cartesian_state(m.path, m.orientation, ms);
    out.t = ms.t;
    out.u = ms.u;
    out.s = ms.s;
    out.segment = ms.segment;
    out.speed = ms.speed;
    out.q_WT = Eigen::Quaterniond(x.X_WT.linear());
  } else {
    const MoveSample& ms = move_sample_;
    out.t = ms.t;
    out.u = ms.u;
    out.s = ms.s;
    out.segment = 0;
    out.speed = ms.speed;
    x = move_state(ms);
    out.q_WT = ms.q_WT;
    if (linear_sampler_) {
      if (const JointReference* roll = std::get<const LinearMovePlan*>(step_)->roll.get()) {
        apply_roll(roll, x);
        out.q_WT = Eigen::Quaterniond(x.X_WT.linear());
      }
    }
  }
  out.has_joints = false;
  if ((joint_sampler_ || joint_path_sampler_) && move_sample_.has_joints) {
    out.has_joints = true;
    JointSample& j = out.joints;
    j.q = move_sample_.q;
    j.q_dot = move_sample_.q_dot;
    j.q_ddot = move_sample_.q_ddot;
    j.converged = true;
    j.iterations = 0;
    j.position_error = 0.0;
    j.orientation_error = 0.0;
    j.manipulability = move_sample_.manipulability;
    j.midpoint_deviation = 0.0;
  } else if (tracker_) {
    // The continuation (JointTracker::follow): where a sample does not follow from the
    // previous one in one step, the interval between them is walked through the same motion.
    out.has_joints = true;
    if (path_between_) {
      if (tracker_->follow(x, *path_between_, out.joints, kSampleContinuation).converged)
        path_between_->mark(*path_sampler_);
    } else {
      const LinearMovePlan& plan = *std::get<const LinearMovePlan*>(step_);
      auto between = cartesian_source([&](double t, CartesianState& state) {
        linear_move_at(plan, t, move_between_);
        state = move_state(move_between_);
        apply_roll(plan.roll.get(), state);
        return true;
      });
      tracker_->follow(x, between, out.joints, kSampleContinuation);
    }
  }
  if (out.has_joints && dynamics_ != nullptr) {
    JointSample& j = out.joints;
    if (compute_torques_) {
      inverse_dynamics(*dynamics_, j.q, j.q_dot, j.q_ddot, dynamics_options(*dynamics_), j.tau);
    } else {
      j.tau.resize(j.q.size());  // the caller's to fill
    }
  } else {
    out.joints.tau.resize(0);
  }
  ++k_;
}

TrajectorySampler::TrajectorySampler(const Trajectory& trajectory, const RobotModel* robot, const JointVector& seed,
                                     const IkOptions& options)
    : trajectory_(&trajectory), robot_(robot), options_(options) {
  start_step(seed);
}

std::size_t TrajectorySampler::step_count() const {
  const auto* sequence = std::get_if<SequenceMotion>(trajectory_);
  return sequence ? sequence->steps.size() : 1;
}

StepRef TrajectorySampler::step(std::size_t i) const {
  const auto ref = [](const StepMotion& m) {
    return std::visit([](const auto& motion) { return StepRef(&motion); }, m);
  };
  return std::visit(Overloaded{[&](const SequenceMotion& m) { return ref(m.steps[i]); },
                               [](const auto& motion) { return StepRef(&motion); }},
                    *trajectory_);
}

void TrajectorySampler::start_step(const JointVector& seed) {
  sampler_.reset();  // its tracker's workspace first
  sampler_.emplace(step(step_), robot_, seed, options_);
  if (!compute_torques_) sampler_->leave_torques();
}

bool TrajectorySampler::next(TrajectorySample& out) {
  const auto* sequence = std::get_if<SequenceMotion>(trajectory_);
  if (sequence != nullptr) {
    // Each step but the last ends with the rest that the next step's first sample repeats:
    // sampled (its joints seed the next step's IK) and not streamed.
    while (step_ + 1 < sequence->steps.size() &&
           sampler_->index() + 1 >= sample_count(sequence->steps[step_])) {
      const bool has_last = sampler_->next(scratch_);
      ++step_;
      start_step(has_last && scratch_.has_joints ? scratch_.joints.q : JointVector());
    }
  }
  if (!sampler_->next(out)) return false;
  finish(out);
  return true;
}

void TrajectorySampler::at(double t, TrajectorySample& out) {
  const auto* sequence = std::get_if<SequenceMotion>(trajectory_);
  if (sequence != nullptr) {
    // A step's final rest seeds the next step's IK, as next() does.
    while (step_ + 1 < sequence->steps.size() && t >= sequence->start_times[step_ + 1]) {
      sampler_->at(duration(sequence->steps[step_]), scratch_);
      ++step_;
      start_step(scratch_.has_joints ? scratch_.joints.q : JointVector());
    }
    sampler_->at(t - sequence->start_times[step_], out);
  } else {
    sampler_->at(t, out);
  }
  finish(out);
}

void TrajectorySampler::leave_torques() {
  compute_torques_ = false;
  if (sampler_) sampler_->leave_torques();
}

void TrajectorySampler::finish(TrajectorySample& out) {
  const auto* sequence = std::get_if<SequenceMotion>(trajectory_);
  if (sequence != nullptr) {
    out.t += sequence->start_times[step_];
    const auto& segments = sequence->segment_steps[step_];
    out.step = out.segment < segments.size() ? segments[out.segment] : sequence->step_index[step_];
  }
  // q and -q are one rotation: keep successive samples in one hemisphere.
  if (out.q_WT.coeffs().dot(previous_q_.coeffs()) < 0.0) out.q_WT.coeffs() *= -1.0;
  previous_q_ = out.q_WT;
  ++k_;
}

}  // namespace geotraj::core
