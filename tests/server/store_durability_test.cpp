// Tests the durability of server/blob_store.cpp and server/metadata_store.cpp
// together: a child process writes rigs, jobs and blobs and acknowledges each,
// then is SIGKILLed; every acknowledged write must be there when the store
// reopens, every blob on disk whole, and recovery must finish every job.
#include "server/store.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <random>
#include <set>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include "tests/server/store_fixture.h"
#include "tests/test_support.h"

namespace {

namespace fs = std::filesystem;
using api::JobStatus;
using server::BlobStore;
using server::JobRecord;
using server::MetadataStore;
using server::RigRecord;
using namespace rigport_test::store;

// ---------------------------------------------------------------------------
// Crash durability: a child process writes and acknowledges, then is SIGKILLed.

void writeLine(int fd, const std::string& line) {
  const std::string text = line + "\n";  // < PIPE_BUF: one atomic write
  const char* p = text.data();
  std::size_t n = text.size();
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      ::_exit(3);
    }
    p += w;
    n -= static_cast<std::size_t>(w);
  }
}

// Runs in the forked child until killed. Acknowledges only after each call returned ok.
[[noreturn]] void runCrashWriter(const fs::path& dir, int fd, unsigned seed) {
  auto opened = MetadataStore::open(dir / "meta.db");
  if (!opened) ::_exit(2);
  auto store = std::move(*opened);
  BlobStore blobs(dir / "blobs");
  std::mt19937 rng(seed);
  for (int i = 0;; ++i) {
    const std::string n = std::to_string(seed) + "-" + std::to_string(i);
    auto rig_blob = blobs.put(randomBytes(1000 + rng() % 300000, rng));
    if (!rig_blob) ::_exit(4);
    RigRecord rig = makeRig("t" + std::to_string(i % 2), "rig-" + n);
    rig.rig_blob = rig.landmarks_blob = *rig_blob;
    rig.components_blob = "";
    if (!store->insertRig(rig).ok()) ::_exit(5);
    writeLine(fd, "R " + rig.tenant + " " + rig.info.id + " " + *rig_blob);

    JobRecord job = makeJob(rig.tenant, "job-" + n, "key-" + n);
    job.inputs = {{"target", *rig_blob}};
    if (!store->insertJob(job).ok()) ::_exit(6);
    writeLine(fd, "J " + job.tenant + " " + job.id);
    if (!store->markRunning(job.id, 1, false).ok()) ::_exit(7);
    if (i % 3 == 2) continue;  // leave some running for recovery
    auto result = blobs.put(randomBytes(1000 + rng() % 300000, rng));
    if (!result) ::_exit(8);
    JobRecord done = finished(job, JobStatus::kSucceeded);
    done.result_blob = *result;
    done.diagnostics_blob = *result;
    if (!store->markFinished(done).ok()) ::_exit(9);
    writeLine(fd, "F " + job.tenant + " " + job.id + " " + *result);
  }
}

TEST(StoreDurability, AcknowledgedWritesSurviveSigkill) {
  std::mt19937 rng(20261121);
  int total_acks = 0;
  for (int round = 0; round < 4; ++round) {
    const fs::path dir = rigport_test::makeTempDir("crash" + std::to_string(round));
    // The same directory is written by two children in turn, so the second
    // one starts on a store that already went through one crash.
    for (int life = 0; life < 2; ++life) {
      int fds[2];
      ASSERT_EQ(::pipe(fds), 0);
      const unsigned seed = static_cast<unsigned>(round * 10 + life);
      const pid_t pid = ::fork();
      ASSERT_GE(pid, 0);
      if (pid == 0) {
        ::close(fds[0]);
        runCrashWriter(dir, fds[1], seed);
      }
      ::close(fds[1]);
      const int delay_ms = 40 + static_cast<int>(rng() % 260);
      std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
      ::kill(pid, SIGKILL);
      int wstatus = 0;
      ASSERT_EQ(::waitpid(pid, &wstatus, 0), pid);
      ASSERT_TRUE(WIFSIGNALED(wstatus) && WTERMSIG(wstatus) == SIGKILL)
          << "writer exited early with status " << (WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1);
      std::string acks;
      char buf[4096];
      ssize_t r;
      while ((r = ::read(fds[0], buf, sizeof buf)) > 0) acks.append(buf, static_cast<std::size_t>(r));
      ::close(fds[0]);

      auto store = openStore(dir / "meta.db");
      ASSERT_TRUE(store) << "store does not reopen after SIGKILL";
      BlobStore blobs(dir / "blobs");
      blobs.removeTemporaries(std::chrono::seconds(0));
      std::istringstream lines(acks);
      std::string line;
      std::set<std::string> finished_ids;
      while (std::getline(lines, line)) {
        if (lines.eof()) break;  // an unterminated last line was never acknowledged
        std::istringstream in(line);
        std::string kind, tenant, id, hash;
        in >> kind >> tenant >> id >> hash;
        ++total_acks;
        if (kind == "R") {
          auto rig = store->getRig(tenant, id);
          ASSERT_TRUE(rig) << "acknowledged rig lost: " << id << " (delay " << delay_ms << " ms)";
          EXPECT_EQ(rig->rig_blob, hash);
          auto bytes = blobs.read(hash);
          EXPECT_TRUE(bytes.ok()) << (bytes.ok() ? "" : bytes.error().message);
        } else if (kind == "J") {
          EXPECT_TRUE(store->getJob(tenant, id)) << "acknowledged job lost: " << id;
        } else if (kind == "F") {
          auto job = store->getJob(tenant, id);
          ASSERT_TRUE(job) << "finished job lost: " << id;
          EXPECT_EQ(job->status, JobStatus::kSucceeded) << id;
          EXPECT_EQ(job->result_blob, hash) << id;
          auto bytes = blobs.read(hash);
          EXPECT_TRUE(bytes.ok()) << (bytes.ok() ? "" : bytes.error().message);
          finished_ids.insert(id);
        } else {
          ADD_FAILURE() << "unexpected ack line: " << line;
        }
      }
      // Every blob file on disk is whole: nothing half-written is servable.
      std::error_code ec;
      for (const auto& entry : fs::recursive_directory_iterator(blobs.root(), ec)) {
        if (!entry.is_regular_file() || entry.path().parent_path().filename() == "tmp") continue;
        auto bytes = blobs.read(entry.path().filename().string());
        EXPECT_TRUE(bytes.ok()) << (bytes.ok() ? "" : bytes.error().message);
      }
      EXPECT_TRUE(!fs::exists(blobs.root() / "tmp") || fs::is_empty(blobs.root() / "tmp"));

      // Recovery as the server does it: requeue running jobs, then finish every one.
      for (const auto& job : store->unfinishedJobs()) {
        EXPECT_EQ(finished_ids.count(job.id), 0u) << "acknowledged finish was lost: " << job.id;
        if (job.status == JobStatus::kRunning) {
      ASSERT_TRUE(store->requeue(job.id).ok());
    }
        ASSERT_TRUE(store->markRunning(job.id, 2, false).ok());
        auto result = blobs.put(bytesOf("recovered " + job.id));
        ASSERT_TRUE(result.ok());
        JobRecord done = finished(job, JobStatus::kSucceeded);
        done.result_blob = *result;
        ASSERT_TRUE(store->markFinished(done).ok());
      }
      EXPECT_TRUE(store->unfinishedJobs().empty());
      const auto counts = store->countJobsByStatus();
      EXPECT_EQ(counts.at(JobStatus::kQueued) + counts.at(JobStatus::kRunning), 0);
    }
  }
  EXPECT_GT(total_acks, 0) << "the writer never acknowledged anything: the test proved nothing";
}

}  // namespace
