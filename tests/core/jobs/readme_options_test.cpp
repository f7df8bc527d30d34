// The README's option tables against the parsers: every option the parser
// knows is in its table with the default the parser gives it, and no other;
// and the normalised options read back to themselves.
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/jobs/retarget_options.h"
#include "core/jobs/transfer_options.h"

namespace {

// Rows "| `key` | `default JSON` | ... |" of the table after the line that
// starts with `intro`.
std::map<std::string, nlohmann::json> readmeTable(const std::string& intro) {
  std::ifstream in(std::filesystem::path(RIGPORT_SOURCE_DIR) / "README.md");
  EXPECT_TRUE(in) << "README.md not found under " << RIGPORT_SOURCE_DIR;
  std::map<std::string, nlohmann::json> rows;
  std::string line;
  bool in_section = false, in_table = false;
  while (std::getline(in, line)) {
    if (!in_section) {
      in_section = line.rfind(intro, 0) == 0;
      continue;
    }
    if (line.rfind("| `", 0) == 0) {
      in_table = true;
      const std::size_t key_end = line.find('`', 3);
      const std::size_t value_start = line.find("| `", key_end) + 3;
      const std::size_t value_end = line.find("` |", value_start);
      const std::string key = line.substr(3, key_end - 3);
      const std::string value = line.substr(value_start, value_end - value_start);
      const auto parsed = nlohmann::json::parse(value, nullptr, false);
      EXPECT_FALSE(parsed.is_discarded()) << "README default of '" << key << "' is not JSON: " << value;
      rows[key] = parsed;
    } else if (in_table && line.rfind('|', 0) != 0) {
      break;  // the table ended
    }
  }
  EXPECT_FALSE(rows.empty()) << "no option table after '" << intro << "' in README.md";
  return rows;
}

void expectTableMatches(const std::map<std::string, nlohmann::json>& table, const nlohmann::json& defaults) {
  for (const auto& [key, value] : defaults.items()) {
    const auto row = table.find(key);
    if (row == table.end()) {
      ADD_FAILURE() << "option '" << key << "' (default " << value.dump() << ") is missing from the README table";
      continue;
    }
    EXPECT_EQ(row->second, value) << "README default of '" << key << "' is " << row->second.dump() << ", the parser's "
                                  << value.dump();
  }
  for (const auto& [key, value] : table) {
    EXPECT_TRUE(defaults.contains(key)) << "README lists '" << key << "', which the parser does not know";
  }
}

// The table after `intro` holds the parser's defaults (`parse` of "{}",
// normalised by `to_json`), and the normalised defaults read back to
// themselves. Returns them.
template <typename Parse, typename ToJson>
std::string checkTable(const std::string& intro, Parse parse, ToJson to_json) {
  auto defaults = parse("{}", "defaults");
  EXPECT_TRUE(defaults) << defaults.error().message;
  if (!defaults) return {};
  const std::string normalised = to_json(*defaults);
  expectTableMatches(readmeTable(intro), nlohmann::json::parse(normalised));
  auto again = parse(normalised, "normalised");
  EXPECT_TRUE(again) << again.error().message;
  if (again) {
    EXPECT_EQ(to_json(*again), normalised);
  }
  return normalised;
}

TEST(ReadmeOptions, TransferTableIsTheParsersDefaults) {
  const std::string defaults = checkTable("Transfer options:", core::parseTransferOptions, core::transferOptionsJson);
  // Options that are not the defaults read back to themselves too.
  const std::string changed = R"({"adaptation": "local", "max_influences": 6, "weight_encoding": "unorm8",
      "side_matching": false, "uvs": true, "shape_exaggeration": {"jawOpen": 1.5}, "refine_iterations": 0,
      "components": {"animations": false}})";
  auto custom = core::parseTransferOptions(changed, "custom");
  ASSERT_TRUE(custom) << custom.error().message;
  const std::string normalised = core::transferOptionsJson(*custom);
  auto custom_again = core::parseTransferOptions(normalised, "normalised");
  ASSERT_TRUE(custom_again) << custom_again.error().message;
  EXPECT_EQ(core::transferOptionsJson(*custom_again), normalised);
  EXPECT_NE(normalised, defaults);
}

TEST(ReadmeOptions, RetargetTableIsTheParsersDefaults) {
  checkTable("Retarget options:", core::parseRetargetOptions, core::retargetOptionsJson);
}

}  // namespace
