// The records' JSON Schemas checked by Python's jsonschema (Debian's python3-jsonschema,
// scripts/deps): how many of a list of JSON objects a schema refuses, and the schemas the build
// installs (share/pneu/schemas, written by pneu-records). PNEU_BINARY_DIR: the build directory.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <unistd.h>

namespace pneu::test {

/// The number of `objects` (one JSON object each) that `schema` refuses, or -1 when the check
/// cannot run (the schema itself is checked as draft 2020-12 first).
inline int refused_by_the_schema(const std::string& schema, const std::vector<std::string>& objects) {
  namespace fs = std::filesystem;
  static int calls = 0;
  const fs::path dir =
      fs::temp_directory_path() / ("pneu_schema_" + std::to_string(::getpid()) + "_" + std::to_string(++calls));
  fs::create_directories(dir);
  std::ofstream(dir / "schema.json") << schema;
  {
    std::ofstream out(dir / "objects.jsonl");
    for (const auto& l : objects) out << l << '\n';
  }
  std::ofstream(dir / "check.py") << "import json, sys, jsonschema\n"
                                     "schema = json.load(open(sys.argv[1]))\n"
                                     "jsonschema.Draft202012Validator.check_schema(schema)\n"
                                     "v = jsonschema.Draft202012Validator(schema)\n"
                                     "print(sum(1 for line in open(sys.argv[2]) if not v.is_valid(json.loads(line))))\n";
  const std::string cmd = "/usr/bin/python3 '" + (dir / "check.py").string() + "' '" + (dir / "schema.json").string() +
                          "' '" + (dir / "objects.jsonl").string() + "' > '" + (dir / "out").string() + "' 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream in(dir / "out");
  int refused = -1;
  if (status == 0) in >> refused;
  fs::remove_all(dir);
  return refused;
}

/// The schema the build installs for the record `name` (empty when there is none).
inline std::string installed_schema(const std::string& name) {
  std::ifstream in(std::filesystem::path(PNEU_BINARY_DIR) / "share/pneu/schemas" / (name + ".schema.json"));
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace pneu::test
