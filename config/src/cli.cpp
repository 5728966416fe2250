#include "pneu/config/cli.hpp"

#include <unistd.h>

#include <iostream>

#include "pneu/config/config.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace pneu::cli {

Args::Args(int argc, char** argv, int first, std::vector<std::string> value_options,
           std::vector<std::string> flags, std::vector<std::string> repeated) {
  const auto contains = [](const std::vector<std::string>& v, const std::string& s) {
    return std::find(v.begin(), v.end(), s) != v.end();
  };
  for (int i = first; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg.rfind("--", 0) != 0 || arg.size() == 2)
      throw UsageError("unexpected argument '" + arg + "'");
    std::string name = arg.substr(2);
    std::optional<std::string> inline_value;
    if (const auto eq = name.find('='); eq != std::string::npos) {
      inline_value = name.substr(eq + 1);
      name = name.substr(0, eq);
    }
    if (contains(flags, name)) {
      if (inline_value) throw UsageError("--" + name + " takes no value");
      values_[name].push_back("");
      continue;
    }
    if (!contains(value_options, name) && !contains(repeated, name))
      throw UsageError("unknown option --" + name);
    if (!inline_value) {
      if (i + 1 >= argc) throw UsageError("--" + name + " needs a value");
      inline_value = argv[++i];
    }
    if (!contains(repeated, name) && values_.count(name))
      throw UsageError("--" + name + " given twice");
    values_[name].push_back(*inline_value);
  }
}

bool Args::flag(const std::string& name) const { return values_.count(name) != 0; }

std::optional<std::string> Args::value(const std::string& name) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return std::nullopt;
  return it->second.back();
}

std::string Args::required(const std::string& name) const {
  auto v = value(name);
  if (!v) throw UsageError("missing --" + name);
  return *v;
}

double Args::number(const std::string& name, double fallback) const {
  const auto v = value(name);
  if (!v) return fallback;
  char* end = nullptr;
  const double d = std::strtod(v->c_str(), &end);
  if (v->empty() || *end != '\0' || !std::isfinite(d))
    throw UsageError("--" + name + ": '" + *v + "' is not a finite number");
  return d;
}

std::vector<std::string> Args::all(const std::string& name) const {
  const auto it = values_.find(name);
  return it == values_.end() ? std::vector<std::string>{} : it->second;
}

int run_main(const char* program, int (*body)(int, char**), int argc, char** argv) noexcept {
  try {
    return body(argc, argv);
  } catch (const UsageError& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return kExitBadInput;
  } catch (const config::ConfigError& e) {
    std::cerr << program << ": config: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return kExitFailure;
  } catch (...) {
    std::cerr << program << ": unknown failure\n";
    return kExitFailure;
  }
}

AtomicFile::AtomicFile(std::filesystem::path path) : path_(std::move(path)) {
  temp_ = path_;
  temp_ += ".partial-" + std::to_string(::getpid());
  out_.open(temp_, std::ios::out | std::ios::trunc);
  if (!out_) throw std::runtime_error(path_.string() + ": cannot create the output file");
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    out_.close();
    std::error_code ec;
    std::filesystem::remove(temp_, ec);
  }
}

void AtomicFile::commit() {
  out_.flush();
  if (!out_) throw std::runtime_error(path_.string() + ": write failed");
  out_.close();
  std::error_code ec;
  std::filesystem::rename(temp_, path_, ec);
  if (ec) throw std::runtime_error(path_.string() + ": cannot move the output into place: " + ec.message());
  committed_ = true;
}

}  // namespace pneu::cli
