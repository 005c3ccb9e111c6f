// Joint waypoints from a file (waypoints.hpp).
#include "waypoints.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include "commands.hpp"

namespace geotraj::cli {
namespace {

using google::protobuf::Value;

// The numbers of a JSON array, or false.
bool numbers_of(const Value& value, std::vector<double>& out) {
  if (value.kind_case() != Value::kListValue) return false;
  for (const Value& x : value.list_value().values()) {
    if (x.kind_case() != Value::kNumberValue) return false;
    out.push_back(x.number_value());
  }
  return true;
}

// A JointTrajectory (or a RobotTrajectory holding one) in JSON.
bool from_json(const Value& root, WaypointFile& out, std::string& error) {
  const Value* trajectory = &root;
  if (root.kind_case() == Value::kStructValue) {
    const auto& fields = root.struct_value().fields();
    if (const auto it = fields.find("joint_trajectory"); it != fields.end()) trajectory = &it->second;
  }
  if (trajectory->kind_case() == Value::kListValue) {  // [[...], [...]]
    for (int i = 0; i < trajectory->list_value().values_size(); ++i) {
      std::vector<double> row;
      if (!numbers_of(trajectory->list_value().values(i), row)) {
        error = "element " + std::to_string(i) + " is not an array of numbers";
        return false;
      }
      out.rows.push_back(std::move(row));
    }
    return true;
  }
  if (trajectory->kind_case() != Value::kStructValue) {
    error = "is neither a JointTrajectory ({\"joint_names\": [...], \"points\": [...]}) nor an array of arrays";
    return false;
  }
  const auto& fields = trajectory->struct_value().fields();
  const auto points = fields.find("points");
  if (points == fields.end() || points->second.kind_case() != Value::kListValue) {
    error = "has no \"points\" array (a trajectory_msgs/JointTrajectory in JSON)";
    return false;
  }
  if (const auto names = fields.find("joint_names"); names != fields.end()) {
    if (names->second.kind_case() != Value::kListValue) {
      error = "\"joint_names\" is not an array of strings";
      return false;
    }
    for (const Value& name : names->second.list_value().values()) {
      if (name.kind_case() != Value::kStringValue) {
        error = "\"joint_names\" is not an array of strings";
        return false;
      }
      out.joint_names.push_back(name.string_value());
    }
  }
  const auto& list = points->second.list_value();
  for (int i = 0; i < list.values_size(); ++i) {
    const Value& point = list.values(i);
    const std::string where = "points[" + std::to_string(i) + "]";
    if (point.kind_case() != Value::kStructValue) {
      error = where + " is not an object";
      return false;
    }
    const auto& pf = point.struct_value().fields();
    const auto positions = pf.find("positions");
    std::vector<double> row;
    if (positions == pf.end() || !numbers_of(positions->second, row)) {
      error = where + ".positions is not an array of numbers";
      return false;
    }
    out.rows.push_back(std::move(row));
  }
  return true;
}

// Text: one waypoint per line.
bool from_text(const std::string& text, WaypointFile& out, std::string& error) {
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    for (char& c : line) {
      if (c == ',' || c == '\t' || c == '\r') c = ' ';
    }
    const auto first = line.find_first_not_of(' ');
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream words(line);
    std::vector<double> row;
    std::vector<std::string> names;
    for (std::string word; words >> word;) {
      double value = 0.0;
      const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), value);
      if (ec == std::errc() && end == word.data() + word.size()) {
        row.push_back(value);
      } else {
        names.push_back(word);
      }
    }
    if (!names.empty()) {
      if (!row.empty() || !out.rows.empty() || !out.joint_names.empty()) {
        error = "line " + std::to_string(number) + ": '" + names.front() + "' is not a number";
        return false;
      }
      out.joint_names = std::move(names);  // a header of joint names
      continue;
    }
    out.rows.push_back(std::move(row));
  }
  return true;
}

}  // namespace

bool read_waypoints(const std::string& path, WaypointFile& out, std::string& error) {
  const std::string name = path == "-" ? "standard input" : path;
  std::string text;
  if (!read_text(path, text)) {
    error = "cannot read " + name;
    return false;
  }
  out = {};
  const auto start = text.find_first_not_of(" \t\r\n");
  bool ok = true;
  std::string why;
  if (start != std::string::npos && (text[start] == '{' || text[start] == '[')) {
    Value root;
    const auto status = google::protobuf::util::JsonStringToMessage(text, &root);
    if (!status.ok()) {
      error = name + " is not JSON: " + std::string(status.message());
      return false;
    }
    ok = from_json(root, out, why);
  } else {
    ok = from_text(text, out, why);
  }
  if (!ok) {
    error = name + ": " + why;
    return false;
  }
  if (out.rows.empty()) {
    error = name + " has no waypoints";
    return false;
  }
  for (std::size_t i = 0; i < out.rows.size(); ++i) {
    if (out.rows[i].size() != out.rows.front().size() ||
        (!out.joint_names.empty() && out.rows[i].size() != out.joint_names.size())) {
      error = name + ": waypoint " + std::to_string(i) + " has " + std::to_string(out.rows[i].size()) + " values, " +
              (out.joint_names.empty() ? "the first " + std::to_string(out.rows.front().size())
                                       : std::to_string(out.joint_names.size()) + " joints are named");
      return false;
    }
    for (const double v : out.rows[i]) {
      if (!std::isfinite(v)) {
        error = name + ": waypoint " + std::to_string(i) + " has a value that is not a finite number";
        return false;
      }
    }
  }
  return true;
}

bool set_joint_path(const WaypointFile& file, const std::vector<std::string>& model_joint_names,
                    double blend_tolerance, v1::PlanRequest& request, std::string& error) {
  // Where each of the model's joints is in the file's rows.
  std::vector<std::size_t> column;
  if (!file.joint_names.empty() && !model_joint_names.empty()) {
    std::vector<bool> used(file.joint_names.size(), false);
    for (const std::string& joint : model_joint_names) {
      std::size_t k = 0;
      while (k < file.joint_names.size() && file.joint_names[k] != joint) ++k;
      if (k == file.joint_names.size()) {
        error = "the waypoints name no joint '" + joint + "' of the robot";
        return false;
      }
      used[k] = true;
      column.push_back(k);
    }
    for (std::size_t k = 0; k < used.size(); ++k) {
      if (!used[k]) {
        error = "the waypoints name a joint '" + file.joint_names[k] + "' that the robot does not have";
        return false;
      }
    }
  } else {
    for (std::size_t k = 0; k < file.rows.front().size(); ++k) column.push_back(k);
  }
  request.clear_path();
  request.clear_joint_move();
  request.clear_linear_move();
  request.clear_sequence();
  v1::JointPath& path = *request.mutable_joint_path();
  path.clear_waypoints();
  for (const auto& row : file.rows) {
    auto& waypoint = *path.add_waypoints();
    for (const std::size_t k : column) waypoint.add_positions(row[k]);
  }
  if (blend_tolerance >= 0.0) path.set_blend_tolerance(blend_tolerance);
  return true;
}

}  // namespace geotraj::cli
