#include "script.hpp"

#include <charconv>
#include <cmath>
#include <optional>
#include <system_error>

namespace geotraj::cli {
namespace {

// One script line as words, with its number and its text (for the messages).
struct Line {
  int number = 0;
  std::string text;
  std::vector<std::string> words;
};

// The lines that hold a command: comments (from `#`) and blank lines dropped.
std::vector<Line> command_lines(std::string_view text) {
  std::vector<Line> lines;
  int number = 0;
  while (!text.empty()) {
    const auto end = text.find('\n');
    std::string_view raw = text.substr(0, end);
    text = end == std::string_view::npos ? std::string_view() : text.substr(end + 1);
    ++number;
    if (const auto hash = raw.find('#'); hash != std::string_view::npos) raw = raw.substr(0, hash);
    Line line{number, std::string(raw), {}};
    std::size_t i = 0;
    const auto space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; };
    while (i < raw.size()) {
      while (i < raw.size() && space(raw[i])) ++i;
      const std::size_t start = i;
      while (i < raw.size() && !space(raw[i])) ++i;
      if (i > start) line.words.emplace_back(raw.substr(start, i - start));
    }
    while (!line.text.empty() && space(line.text.back())) line.text.pop_back();
    if (!line.words.empty()) lines.push_back(std::move(line));
  }
  return lines;
}

// A finite number (the whole word), or nothing.
std::optional<double> number(const std::string& word) {
  double value = 0.0;
  const char* end = word.data() + word.size();
  const auto [ptr, ec] = std::from_chars(word.data(), end, value);
  if (ec != std::errc() || ptr != end || !std::isfinite(value)) return std::nullopt;
  return value;
}

// Collects the messages of one script.
struct Report {
  std::string name;
  ScriptErrors errors;
  void add(const Line& line, const std::string& what) {
    errors.push_back("script " + name + ", line " + std::to_string(line.number) + ": " + what + ": `" + line.text +
                     "`");
  }
};

// The time of a line (its first word): >= 0 and not before `previous`; nothing (reported)
// otherwise.
std::optional<double> line_time(const Line& line, double previous, Report& report) {
  const auto t = number(line.words[0]);
  if (!t) {
    report.add(line, "the time \"" + line.words[0] + "\" is not a number of seconds (a line is TIME COMMAND [ARGS])");
    return std::nullopt;
  }
  if (*t < 0.0) {
    report.add(line, "the time must be >= 0 s, got " + line.words[0]);
    return std::nullopt;
  }
  if (*t < previous) {
    report.add(line, "the time " + line.words[0] + " s is before the previous line's; the lines go in time order");
    return std::nullopt;
  }
  return t;
}

// The time of the command on `line`, in order after `previous` (which it then becomes);
// nothing (reported) when the line comes after the stop on line `stop_line` (0: none yet),
// its time is not valid, or no command follows it (`usage` lists the commands).
std::optional<double> command_time(const Line& line, int stop_line, double& previous, Report& report,
                                   const std::string& usage) {
  if (stop_line > 0) {
    report.add(line, "comes after the stop on line " + std::to_string(stop_line) + ", where the call ends");
    return std::nullopt;
  }
  const auto t = line_time(line, previous, report);
  if (!t) return std::nullopt;
  previous = *t;
  if (line.words.size() < 2) {
    report.add(line, "no command after the time (" + usage + ")");
    return std::nullopt;
  }
  return t;
}

// The words from `first` on as fractions in [-1, 1]; false (reported) when one is not.
bool fractions(const Line& line, std::size_t first, std::vector<double>& out, Report& report) {
  bool ok = true;
  for (std::size_t i = first; i < line.words.size(); ++i) {
    const auto v = number(line.words[i]);
    if (!v || *v < -1.0 || *v > 1.0) {
      report.add(line, "value " + std::to_string(i - first + 1) + " \"" + line.words[i] +
                           "\" is not a fraction of the maximum in [-1, 1]");
      ok = false;
      continue;
    }
    out.push_back(*v);
  }
  return ok;
}

}  // namespace

tl::expected<std::vector<ExecuteStep>, ScriptErrors> parse_execute_script(std::string_view text,
                                                                          const std::string& name) {
  Report report{name, {}};
  std::vector<ExecuteStep> steps;
  double previous = 0.0;
  int stop_line = 0;
  for (const Line& line : command_lines(text)) {
    const auto t = command_time(line, stop_line, previous, report, "override PCT, pause, resume or stop");
    if (!t) continue;
    ExecuteStep step;
    step.t_s = *t;
    step.line = line.number;
    const std::string& command = line.words[1];
    const std::size_t args = line.words.size() - 2;
    if (command == "override") {
      const auto percent = args == 1 ? number(line.words[2]) : std::nullopt;
      if (!percent || *percent < 0.0 || *percent > 100.0) {
        report.add(line, "override takes one percentage in [0, 100]");
        continue;
      }
      step.kind = ExecuteStep::Kind::kOverride;
      step.percent = *percent;
    } else if (command == "pause" || command == "resume" || command == "stop") {
      if (args != 0) {
        report.add(line, command + " takes no argument");
        continue;
      }
      step.kind = command == "pause"    ? ExecuteStep::Kind::kPause
                  : command == "resume" ? ExecuteStep::Kind::kResume
                                        : ExecuteStep::Kind::kStop;
      if (step.kind == ExecuteStep::Kind::kStop) stop_line = line.number;
    } else {
      report.add(line, "unknown command \"" + command + "\" (override PCT, pause, resume or stop)");
      continue;
    }
    steps.push_back(step);
  }
  if (!report.errors.empty()) return tl::unexpected(std::move(report.errors));
  return steps;
}

tl::expected<std::vector<JogStep>, ScriptErrors> parse_jog_script(std::string_view text, const std::string& name) {
  Report report{name, {}};
  std::vector<JogStep> steps;
  double previous = 0.0;
  int stop_line = 0;
  int joints_line = 0;  // the first `joints` line: every other one has as many values
  std::size_t joint_count = 0;
  for (const Line& line : command_lines(text)) {
    const auto t = command_time(line, stop_line, previous, report,
                                "joints V..., twist world|tool VX VY VZ WX WY WZ, or stop");
    if (!t) continue;
    JogStep step;
    step.t_s = *t;
    step.line = line.number;
    const std::string& command = line.words[1];
    if (command == "joints") {
      step.kind = JogStep::Kind::kJoints;
      if (line.words.size() == 2) {
        report.add(line, "joints takes one value per joint, each in [-1, 1]");
        continue;
      }
      if (!fractions(line, 2, step.values, report)) continue;
      if (joints_line == 0) {
        joints_line = line.number;
        joint_count = step.values.size();
      } else if (step.values.size() != joint_count) {
        report.add(line, "joints has " + std::to_string(step.values.size()) + " values, but line " +
                             std::to_string(joints_line) + " has " + std::to_string(joint_count) +
                             " (one per joint)");
        continue;
      }
    } else if (command == "twist") {
      step.kind = JogStep::Kind::kTwist;
      if (line.words.size() != 9 || (line.words[2] != "world" && line.words[2] != "tool")) {
        report.add(line, "twist takes a frame (world or tool) and six values vx vy vz wx wy wz, each in [-1, 1]");
        continue;
      }
      step.tool_frame = line.words[2] == "tool";
      if (!fractions(line, 3, step.values, report)) continue;
    } else if (command == "stop") {
      if (line.words.size() != 2) {
        report.add(line, "stop takes no argument");
        continue;
      }
      step.kind = JogStep::Kind::kStop;
      stop_line = line.number;
    } else {
      report.add(line, "unknown command \"" + command + "\" (joints, twist or stop)");
      continue;
    }
    steps.push_back(std::move(step));
  }
  if (!report.errors.empty()) return tl::unexpected(std::move(report.errors));
  return steps;
}

}  // namespace geotraj::cli
