// Test support: a gmock matcher for pneu::config::ConfigError.
#pragma once

#include <gmock/gmock.h>

#include <string>

#include "pneu/config/config.hpp"

namespace pneu::test {

// A ConfigError whose key_path() and what() match; what() reads "<key.path>: <reason>".
MATCHER_P2(IsConfigError, key_path_matcher, message_matcher,
           "is a ConfigError whose key path " +
               ::testing::DescribeMatcher<std::string>(key_path_matcher) + " and whose message " +
               ::testing::DescribeMatcher<std::string>(message_matcher)) {
  *result_listener << "key path \"" << arg.key_path() << "\", message \"" << arg.what() << "\"";
  return ::testing::Matches(key_path_matcher)(arg.key_path()) &&
         ::testing::Matches(message_matcher)(std::string(arg.what()));
}

}  // namespace pneu::test
