// Job ids as users type them (JobRegistry::Resolve through Scheduler::Status, the path of every
// RPC that takes a job id): a whole id, a unique prefix with or without "job-", an ambiguous
// prefix (InputError naming the field and listing the candidates) and no match (NotFoundError).
#include "server/jobs/job_registry.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "server/errors.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
using ::testing::HasSubstr;
using testing::MakeConfig;
using testing::MultipleMaps;

class JobIdTest : public testing::SchedulerFixture {};

TEST_F(JobIdTest, UniquePrefixesResolveAndAmbiguousOnesListTheCandidates) {
  // 17 ids of random hex: two of them share their first digit (16 digits).
  std::vector<std::string> ids;
  for (int i = 0; i < 17; ++i) ids.push_back(Submit(MakeConfig(MultipleMaps(1, 0), 8, 4)));
  std::map<char, std::vector<std::string>> by_first;
  for (const std::string& id : ids) {
    ASSERT_EQ(id.rfind(kJobIdPrefix, 0), 0u) << id;
    ASSERT_GT(id.size(), kJobIdPrefix.size() + 8) << id;
    by_first[id[kJobIdPrefix.size()]].push_back(id);
    EXPECT_EQ(scheduler_.Status(id).job_id(), id);  // the whole id
  }
  for (const std::string& id : ids) {
    // The shortest prefix no other id shares.
    size_t n = kJobIdPrefix.size() + 1;
    auto shared = [&](size_t len) {
      for (const std::string& other : ids)
        if (other != id && other.compare(0, len, id, 0, len) == 0) return true;
      return false;
    };
    while (shared(n)) ++n;
    EXPECT_EQ(scheduler_.Status(id.substr(0, n)).job_id(), id);
    EXPECT_EQ(scheduler_.Status(id.substr(kJobIdPrefix.size(), n - kJobIdPrefix.size())).job_id(), id);
  }
  bool checked_ambiguous = false;
  for (const auto& [digit, group] : by_first) {
    if (group.size() < 2) continue;
    try {
      scheduler_.Status(std::string(1, digit));
      ADD_FAILURE() << "prefix " << digit << " of " << group.size() << " jobs resolved";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("job_id"));
      EXPECT_THAT(e.what(), HasSubstr("ambiguous"));
      for (const std::string& id : group) EXPECT_THAT(e.what(), HasSubstr(id));
    }
    checked_ambiguous = true;
  }
  EXPECT_TRUE(checked_ambiguous);
}

TEST_F(JobIdTest, NoMatchIsNotFoundAndTheBarePrefixMatchesNothing) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 8, 4));
  EXPECT_THROW(scheduler_.Status("zz"), NotFoundError);
  EXPECT_THROW(scheduler_.Status(id + "0"), NotFoundError);  // longer than the id
  EXPECT_THROW(scheduler_.Status(kJobIdPrefix), NotFoundError);
  EXPECT_THROW(scheduler_.Status(""), NotFoundError);
  EXPECT_THROW(scheduler_.Cancel("zz"), NotFoundError);
  EXPECT_EQ(scheduler_.Cancel(id.substr(0, kJobIdPrefix.size() + 3)).job_id(), id);
}

}  // namespace
}  // namespace pf::server
