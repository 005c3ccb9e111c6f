// A temporary FILE* (for a logger's output) whose contents the test reads back.
#pragma once

#include <cstddef>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

namespace geotraj::testing {

class FileCapture {
 public:
  FileCapture() : file_(std::tmpfile()) {}
  ~FileCapture() { std::fclose(file_); }
  FileCapture(const FileCapture&) = delete;
  FileCapture& operator=(const FileCapture&) = delete;

  std::FILE* file() const { return file_; }
  /// Everything written so far.
  std::string text() const {
    std::fflush(file_);
    std::rewind(file_);
    std::string out;
    char buffer[4096];
    for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, file_)) > 0;) out.append(buffer, n);
    return out;
  }
  std::vector<std::string> lines() const {
    std::vector<std::string> out;
    std::istringstream in(text());
    for (std::string line; std::getline(in, line);) out.push_back(line);
    return out;
  }

 private:
  std::FILE* file_;
};

}  // namespace geotraj::testing
