// fuzz_seed_tool OUT_DIR EXAMPLES_DIR EXTRA_DIR: the fuzz targets' seed corpora and
// dictionaries, made at build time so that they follow every change of the API:
//
//   OUT_DIR/seeds/fuzz_plan_request/       every EXAMPLES_DIR/*.json that is a PlanRequest, binary
//   OUT_DIR/seeds/fuzz_plan_request_json/  the same files as they are (proto3 JSON)
//   OUT_DIR/seeds/fuzz_convert/            every one that is a ConvertRequest, binary
//   OUT_DIR/seeds/fuzz_robot_model_json/   the built-in robot models and every request's
//                                          robot.model, as robot model files (proto3 JSON)
//   OUT_DIR/seeds/fuzz_http_head/          the hand-written request heads
//   OUT_DIR/seeds/fuzz_kinematics/         every example that is a Forward- or
//                                          InverseKinematicsRequest, binary after its
//                                          selector byte (0 forward, 1 inverse)
//   OUT_DIR/seeds/fuzz_live/               every example PlanRequest with a motion executed with
//                                          an override, a pause, a resume and a stop; a jog of
//                                          each built-in arm (selector byte 0 Execute, 1 Jog,
//                                          then length-prefixed binary messages)
//   OUT_DIR/seeds/fuzz_urdf/               the hand-written URDF documents as they are (the
//                                          default options), and variants of each after a
//                                          selector byte (fuzz_urdf.cpp): its first link as
//                                          baseLink and its last as tipLink, a link in the
//                                          middle as tipLink alone, accelerations not
//                                          required, and jointLimits for its first joint
//   OUT_DIR/seeds/fuzz_joint_limits_yaml/  the hand-written joint_limits.yaml files as they are
//   OUT_DIR/seeds/fuzz_web/                every example posted (HTTP/1.1) to each route that
//                                          takes it; GET /v1/robots, GET /, a wrong method,
//                                          two requests on one connection, a chunked body
//   OUT_DIR/<target>.dict                  for the JSON targets: every field name (JSON and
//                                          proto spelling) and enum value of the messages,
//                                          and the JSON tokens of proto3's special numbers;
//                                          for fuzz_http_head, fuzz_web and fuzz_urdf, the
//                                          words of their languages
//
// EXTRA_DIR/<target>/ holds hand-written seeds (tests/fuzz/corpus): added as they are to the
// JSON targets; for the binary targets a *.json file is converted, any other file is copied.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>
#include <google/protobuf/util/json_util.h>

#include "core/robot/robot.hpp"
#include "geotraj/v1/geotraj.pb.h"
#include "server/wire/convert.hpp"

namespace fs = std::filesystem;
namespace pb = google::protobuf;

namespace {

std::string read(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void write(const fs::path& file, const std::string& bytes) {
  fs::create_directories(file.parent_path());
  std::ofstream out(file, std::ios::binary);
  out << bytes;
  if (!out) {
    std::fprintf(stderr, "fuzz_seed_tool: cannot write %s\n", file.c_str());
    std::exit(1);
  }
}

template <class M>
bool parse_json(const std::string& text, M& message) {
  return pb::util::JsonStringToMessage(text, &message).ok();
}

// Whether `text` is a message of type `descriptor` in proto3 JSON.
bool parses_as(const std::string& text, const pb::Descriptor* descriptor) {
  std::unique_ptr<pb::Message> message(pb::MessageFactory::generated_factory()->GetPrototype(descriptor)->New());
  return pb::util::JsonStringToMessage(text, message.get()).ok();
}

// A POST of `body` to `route` as an HTTP/1.1 client sends it.
std::string http_post(const std::string& route, const std::string& body) {
  return "POST " + route + " HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: " +
         std::to_string(body.size()) + "\r\n\r\n" + body;
}

std::string to_json(const pb::Message& message) {
  std::string json;
  pb::util::JsonPrintOptions options;
  options.add_whitespace = true;
  (void)pb::util::MessageToJsonString(message, &json, options);
  return json;
}

std::vector<fs::path> files_in(const fs::path& dir, bool json_only) {
  std::vector<fs::path> files;
  if (!fs::is_directory(dir)) return files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    if (json_only && entry.path().extension() != ".json") continue;
    files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

// Field names and enum values reachable from `descriptor`.
void collect_tokens(const pb::Descriptor* descriptor, std::set<const pb::Descriptor*>& seen,
                    std::set<std::string>& tokens) {
  if (!seen.insert(descriptor).second) return;
  for (int i = 0; i < descriptor->field_count(); ++i) {
    const pb::FieldDescriptor* field = descriptor->field(i);
    tokens.insert("\"" + field->json_name() + "\"");
    tokens.insert("\"" + field->name() + "\"");
    if (const auto* e = field->enum_type()) {
      for (int v = 0; v < e->value_count(); ++v) tokens.insert("\"" + e->value(v)->name() + "\"");
    }
    if (const auto* m = field->message_type()) collect_tokens(m, seen, tokens);
  }
}

// A libFuzzer dictionary entry: `token` quoted, with '"', '\\' and bytes outside printable
// ASCII escaped.
std::string dictionary_entry(const std::string& token) {
  std::string out = "\"";
  for (const char c : token) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (u < 0x20 || u >= 0x7f) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02X", u);
      out += hex;
    } else {
      out += c;
    }
  }
  return out + "\"\n";
}

// The names of a URDF document's <link name=".."> (or <joint name="..">, `tag` "joint")
// elements, in document order (a plain scan, enough for the seeds: no XML parser here).
std::vector<std::string> urdf_names(const std::string& text, const std::string& tag) {
  std::vector<std::string> names;
  const std::string open = "<" + tag + " name=\"";
  for (std::size_t at = text.find(open); at != std::string::npos; at = text.find(open, at + 1)) {
    const std::size_t begin = at + open.size();
    const std::size_t end = text.find('"', begin);
    if (end == std::string::npos) break;
    names.push_back(text.substr(begin, end - begin));
  }
  return names;
}

void write_dictionary(const fs::path& file, const pb::Descriptor* root) {
  std::set<const pb::Descriptor*> seen;
  std::set<std::string> tokens{"\"NaN\"",  "\"Infinity\"", "\"-Infinity\"", "1e308", "-1e308", "4.9e-324", "1e-300",
                               "true",     "false",        "null",           "[]",    "{}",     ":",        ",",
                               "\"1e400\"", "-0",          "2147483647",     "4294967295", "18446744073709551615"};
  collect_tokens(root, seen, tokens);
  std::string text = "# libFuzzer dictionary for " + root->full_name() + " in proto3 JSON (made by fuzz_seed_tool)\n";
  for (const auto& token : tokens) {
    std::string escaped;
    for (char c : token) {
      if (c == '"' || c == '\\') escaped += '\\';
      escaped += c;
    }
    text += "\"" + escaped + "\"\n";
  }
  write(file, text);
}

// A fuzz_live input: the selector byte, then each message as a 2-byte little-endian length
// and its binary form.
template <class Message>
std::string live_seed(char selector, const std::vector<Message>& run) {
  std::string out(1, selector);
  for (const auto& m : run) {
    const std::string bytes = m.SerializeAsString();
    out += static_cast<char>(bytes.size() & 0xffu);
    out += static_cast<char>((bytes.size() >> 8) & 0xffu);
    out += bytes;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: fuzz_seed_tool OUT_DIR EXAMPLES_DIR EXTRA_DIR\n");
    return 2;
  }
  const fs::path out = argv[1];
  const fs::path examples = argv[2];
  const fs::path extra = argv[3];
  const fs::path seeds = out / "seeds";
  int counts[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};

  // The documented example requests.
  for (const auto& file : files_in(examples, true)) {
    const std::string text = read(file);
    const std::string stem = file.stem().string();
    geotraj::v1::PlanRequest plan;
    if (parse_json(text, plan)) {
      write(seeds / "fuzz_plan_request_json" / (stem + ".json"), text);
      write(seeds / "fuzz_plan_request" / (stem + ".bin"), plan.SerializeAsString());
      counts[0]++;
      counts[1]++;
      if (plan.robot().has_model()) {
        write(seeds / "fuzz_robot_model_json" / (stem + "_robot.json"), to_json(plan.robot().model()));
        counts[3]++;
      }
    }
    if (parse_json(text, plan) && plan.has_motion()) {
      // fuzz_live: the plan executed with an override change, a pause, a resume and a stop.
      std::vector<geotraj::v1::ExecuteRequest> run(5);
      *run[0].mutable_plan() = plan;
      run[0].mutable_plan()->mutable_robot()->clear_report_only();
      run[0].mutable_options()->set_deadman_s(1.0);
      run[1].set_speed_override(50.0);
      run[2].mutable_pause();
      run[3].mutable_resume();
      run[4].mutable_stop();
      write(seeds / "fuzz_live" / (stem + "_execute.bin"), live_seed('\0', run));
      counts[7]++;
    }
    geotraj::v1::ExecuteRequest execute;
    geotraj::v1::JogRequest jog;
    if (parse_json(text, execute) && execute.has_plan()) {  // the grpcurl files of the live calls
      write(seeds / "fuzz_live" / (stem + ".bin"), live_seed('\0', std::vector<geotraj::v1::ExecuteRequest>{execute}));
      counts[7]++;
    } else if (parse_json(text, jog) && jog.has_start()) {
      write(seeds / "fuzz_live" / (stem + ".bin"), live_seed('\1', std::vector<geotraj::v1::JogRequest>{jog}));
      counts[7]++;
    }
    // fuzz_web: the file posted to each route that takes it, as a client sends it.
    for (const auto& [route, message] : std::initializer_list<std::pair<const char*, const pb::Descriptor*>>{
             {"/v1/plan", geotraj::v1::PlanRequest::descriptor()},
             {"/v1/analyze", geotraj::v1::PlanRequest::descriptor()},
             {"/v1/stream", geotraj::v1::PlanRequest::descriptor()},
             {"/v1/convert", geotraj::v1::ConvertRequest::descriptor()},
             {"/v1/fk", geotraj::v1::ForwardKinematicsRequest::descriptor()},
             {"/v1/ik", geotraj::v1::InverseKinematicsRequest::descriptor()}}) {
      if (!parses_as(text, message)) continue;
      const std::string name = std::string(route).substr(4);
      write(seeds / "fuzz_web" / (stem + "_" + name + ".http"), http_post(route, text));
      counts[8]++;
    }
    geotraj::v1::ForwardKinematicsRequest forward;
    geotraj::v1::InverseKinematicsRequest inverse;
    if (parse_json(text, forward)) {
      write(seeds / "fuzz_kinematics" / (stem + ".bin"), std::string(1, '\0') + forward.SerializeAsString());
      counts[5]++;
    } else if (parse_json(text, inverse)) {
      write(seeds / "fuzz_kinematics" / (stem + ".bin"), std::string(1, '\1') + inverse.SerializeAsString());
      counts[5]++;
    }
    geotraj::v1::ConvertRequest convert;
    if (parse_json(text, convert)) {
      write(seeds / "fuzz_convert" / (stem + ".bin"), convert.SerializeAsString());
      counts[2]++;
    } else if (plan.has_path()) {  // the path of a PlanRequest is a ConvertRequest's as well
      *convert.mutable_path() = plan.path();
      write(seeds / "fuzz_convert" / (stem + "_path.bin"), convert.SerializeAsString());
      counts[2]++;
    }
  }
  // The built-in robot models, in the form of a robot model file.
  for (const auto& model : geotraj::core::builtin_robots()) {
    geotraj::v1::RobotModel wire;
    geotraj::server::to_proto(model, wire);
    write(seeds / "fuzz_robot_model_json" / ("builtin_" + model.name + ".json"), to_json(wire));
    counts[3]++;
  }
  // Hand-written seeds.
  for (const auto& file : files_in(extra / "fuzz_plan_request_json", false)) {
    write(seeds / "fuzz_plan_request_json" / file.filename(), read(file));
    counts[1]++;
  }
  for (const auto& file : files_in(extra / "fuzz_robot_model_json", false)) {
    write(seeds / "fuzz_robot_model_json" / file.filename(), read(file));
    counts[3]++;
  }
  for (const char* target : {"fuzz_plan_request", "fuzz_convert"}) {
    const bool is_plan = std::string(target) == "fuzz_plan_request";
    for (const auto& file : files_in(extra / target, false)) {
      std::string bytes = read(file);
      if (file.extension() == ".json") {
        geotraj::v1::PlanRequest plan;
        geotraj::v1::ConvertRequest convert;
        const bool ok = is_plan ? parse_json(bytes, plan) : parse_json(bytes, convert);
        if (!ok) {
          std::fprintf(stderr, "fuzz_seed_tool: %s is not a %s in proto3 JSON\n", file.c_str(),
                       is_plan ? "PlanRequest" : "ConvertRequest");
          return 1;
        }
        bytes = is_plan ? plan.SerializeAsString() : convert.SerializeAsString();
      }
      write(seeds / target / (file.stem().string() + ".bin"), bytes);
      counts[is_plan ? 0 : 2]++;
    }
  }
  for (const auto& file : files_in(extra / "fuzz_http_head", false)) {
    write(seeds / "fuzz_http_head" / file.filename(), read(file));
    counts[4]++;
  }
  // The words of an HTTP/1.1 request head (RFC 9110, 9112) for fuzz_http_head.
  std::string http_words;
  for (const char* word : {"GET", "HEAD", "POST", "OPTIONS", " /metrics", " /healthz", "?", " HTTP/1.1", " HTTP/1.0",
                           "\\x0D\\x0A", "\\x0D\\x0A\\x0D\\x0A", ": ", "Host", "Content-Length", "Transfer-Encoding",
                           "chunked", "Range", "bytes=0-", "Connection", "keep-alive", "Expect", "100-continue",
                           "Accept-Encoding", "gzip", "br"}) {
    http_words += "\"" + std::string(word) + "\"\n";
  }
  write(out / "fuzz_http_head.dict", http_words);
  // fuzz_urdf: the hand-written documents as they are, and with options after a selector
  // byte (fuzz_urdf.cpp: bit 2 an options byte, bit 0 a baseLink, bit 1 a tipLink, each up
  // to '\n'; options bit 0 accelerations not required, bits 1-2 how many jointLimits follow).
  for (const auto& file : files_in(extra / "fuzz_urdf", false)) {
    const std::string text = read(file);
    const std::string stem = file.stem().string();
    const auto variant = [&](const std::string& suffix, const std::string& prefix) {
      write(seeds / "fuzz_urdf" / (stem + suffix + ".bin"), prefix + text);
      counts[6]++;
    };
    write(seeds / "fuzz_urdf" / file.filename(), text);
    counts[6]++;
    variant("_kinematics", std::string("\4\1", 2));
    const std::vector<std::string> joints = urdf_names(text, "joint");
    if (!joints.empty()) variant("_joint_limits", std::string("\4\2", 2) + joints.front() + "\n\x08\x10\x20");
    const std::vector<std::string> links = urdf_names(text, "link");
    if (links.size() < 2) continue;
    variant("_base_tip", std::string(1, '\3') + links.front() + "\n" + links.back() + "\n");
    variant("_mid_tip", std::string(1, '\2') + links[links.size() / 2] + "\n");
  }
  // fuzz_joint_limits_yaml: the hand-written MoveIt files as they are, and the words of the
  // format and of YAML.
  for (const auto& file : files_in(extra / "fuzz_joint_limits_yaml", false))
    write(seeds / "fuzz_joint_limits_yaml" / file.filename(), read(file));
  std::string yaml_words;
  for (const char* word : {"joint_limits:", "has_velocity_limits: ", "max_velocity: ", "has_acceleration_limits: ",
                           "max_acceleration: ", "has_jerk_limits: ", "max_jerk: ", "has_effort_limits: ",
                           "max_effort: ", "true", "false", "\\x0A  ", "\\x0A    ", "{", "}", "[", "]", "&a ", "*a", "---",
                           "!!float ", ".inf", ".nan", "1e308", "5e-324", "- "}) {
    yaml_words += "\"" + std::string(word) + "\"\n";
  }
  write(out / "fuzz_joint_limits_yaml.dict", yaml_words);
  // The words of URDF (the elements and attributes urdfdom reads), of the <geotraj> block
  // (planner/robots.hpp), of XML, and numbers at the edges of what the reader accepts.
  std::string urdf_words;
  for (const char* word :
       {"<?xml version=\"1.0\"?>", "<?xml version=\"1.0\" encoding=\"UTF-8\"?>", "<robot name=\"", "</robot>",
        "<link name=\"", "</link>", "<joint name=\"", "</joint>", "\" type=\"", "revolute", "continuous", "prismatic",
        "fixed", "floating", "planar", "<parent link=\"", "<child link=\"", "<origin xyz=\"", "\" rpy=\"",
        "<origin rpy=\"", "<axis xyz=\"", "<limit lower=\"", "\" upper=\"", "\" effort=\"", "\" velocity=\"",
        "<mimic joint=\"", "\" multiplier=\"", "\" offset=\"", "<dynamics damping=\"", "\" friction=\"",
        "<calibration rising=\"", "<safety_controller soft_lower_limit=\"", "<inertial>", "<mass value=\"",
        "<inertia ixx=\"", "<visual>", "<collision>", "<geometry>", "<box size=\"", "<material name=\"",
        "<color rgba=\"", "<gazebo>", "<transmission name=\"", "<geotraj", "</geotraj>", " description=\"",
        " base_link=\"", " tip_link=\"", "\" max_acceleration=\"", "\" max_jerk=\"", "\" home=\"", "\"/>", "/>", ">",
        "<!--", "-->", "<![CDATA[", "]]>", "&amp;", "&lt;", "&quot;", "&#x41;", "&#65;", "1e308", "-1e308", "1e309",
        "4.9e-324", "1e6", "1000001", "-1e6", "nan", "inf", "-inf", "0x1p3", "3.14159265358979", " 0 0 1",
        "\n"}) {
    urdf_words += dictionary_entry(word);
  }
  write(out / "fuzz_urdf.dict", urdf_words);
  // fuzz_live: jogs of each built-in arm, joint by joint and Cartesian in both frames.
  for (const char* name : {"pa10", "ur5", "panda", "iiwa14", "ur5e"}) {
    std::vector<geotraj::v1::JogRequest> run(4);
    run[0].mutable_start()->mutable_robot()->set_name(name);
    run[0].mutable_start()->set_cycle_rate_hz(250.0);
    const int dof = std::string(name) == "ur5" || std::string(name) == "ur5e" ? 6 : 7;
    for (int j = 0; j < dof; ++j) run[1].mutable_joints()->add_velocities(j == 1 ? 1.0 : -0.25);
    run[2].mutable_twist()->mutable_linear()->set_x(0.5);
    run[2].mutable_twist()->mutable_angular()->set_z(-0.5);
    run[2].mutable_twist()->set_frame(geotraj::v1::COORDINATE_MODE_TOOL);
    run[3].mutable_stop();
    write(seeds / "fuzz_live" / (std::string("jog_") + name + ".bin"), live_seed('\1', run));
    counts[7]++;
  }
  // fuzz_web: the GET routes, a wrong method, two requests on one connection, a chunked body.
  const std::string robots = "GET /v1/robots HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
  write(seeds / "fuzz_web" / "robots.http", robots);
  write(seeds / "fuzz_web" / "page.http", "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  write(seeds / "fuzz_web" / "wrong_method.http", "GET /v1/plan HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  write(seeds / "fuzz_web" / "two_requests.http", robots + http_post("/v1/plan", "{\"path\": {}}"));
  write(seeds / "fuzz_web" / "chunked.http",
        "POST /v1/convert HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: chunked\r\n\r\n"
        "a\r\n{\"path\": {\r\n2\r\n}}\r\n0\r\n\r\n");
  counts[8] += 5;
  std::string web_words = http_words;
  for (const char* word : {"/v1/plan", "/v1/analyze", "/v1/stream", "/v1/convert", "/v1/fk", "/v1/ik", "/v1/robots",
                           "Authorization", "Bearer ", "X-Request-Id", "application/json", "{", "}", "[", "]", "\\\"",
                           "null", "true", "1e308", "NaN", "-Infinity"}) {
    web_words += dictionary_entry(word);
  }
  write(out / "fuzz_web.dict", web_words);
  write_dictionary(out / "fuzz_plan_request_json.dict", geotraj::v1::PlanRequest::descriptor());
  write_dictionary(out / "fuzz_robot_model_json.dict", geotraj::v1::RobotModel::descriptor());
  std::printf("fuzz_seed_tool: seeds: %d fuzz_plan_request, %d fuzz_plan_request_json, %d fuzz_convert, "
              "%d fuzz_robot_model_json, %d fuzz_http_head, %d fuzz_kinematics, %d fuzz_urdf, %d fuzz_live, %d fuzz_web\n",
              counts[0], counts[1], counts[2], counts[3], counts[4], counts[5], counts[6], counts[7], counts[8]);
  return 0;
}
