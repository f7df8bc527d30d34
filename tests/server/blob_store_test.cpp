// Tests server/blob_store.cpp: content-addressed blobs (round trip,
// idempotence, hash verification, adopt, never visible half-written, temp
// cleanup), the SHA-256 of bytes and files, and the secure random ids.
#include "api/content_id.h"
#include "server/store.h"

#include <sys/stat.h>

#include <atomic>
#include <fstream>
#include <random>
#include <regex>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "tests/server/store_fixture.h"
#include "tests/test_support.h"

namespace {

namespace fs = std::filesystem;
using server::BlobStore;
using namespace rigport_test::store;

// ---------------------------------------------------------------------------
// Blobs

TEST(Sha256, MatchesKnownVectors) {
  EXPECT_EQ(api::sha256Hex(bytesOf("abc")), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(api::sha256Hex(std::span<const std::uint8_t>{}), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  const fs::path dir = rigport_test::makeTempDir("sha");
  std::mt19937 rng(1);
  const auto bytes = randomBytes(300000, rng);  // several read chunks
  std::ofstream(dir / "f", std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  auto file_hash = server::sha256HexOfFile(dir / "f");
  ASSERT_TRUE(file_hash.ok()) << file_hash.error().message;
  EXPECT_EQ(*file_hash, api::sha256Hex(bytes));
  auto missing = server::sha256HexOfFile(dir / "missing");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find((dir / "missing").string()), std::string::npos) << missing.error().message;
}

TEST(SecureRandomHex, GivesDistinctLowerCaseHexOfTheAskedLength) {
  std::set<std::string> seen;
  for (int i = 0; i < 64; ++i) {
    auto hex = server::secureRandomHex(16);
    ASSERT_TRUE(hex);
    EXPECT_TRUE(std::regex_match(*hex, std::regex("[0-9a-f]{32}"))) << *hex;
    seen.insert(*hex);
  }
  EXPECT_EQ(seen.size(), 64u);
}

TEST(BlobStore, PutThenReadReturnsTheBytesUnderTheirHash) {
  BlobStore blobs(rigport_test::makeTempDir("blobs") / "store");
  const auto bytes = bytesOf("abc");
  auto hash = blobs.put(bytes);
  ASSERT_TRUE(hash.ok()) << hash.error().message;
  EXPECT_EQ(*hash, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(blobs.pathOf(*hash), blobs.root() / "ba" / *hash);
  EXPECT_TRUE(fs::is_regular_file(blobs.pathOf(*hash)));
  EXPECT_TRUE(blobs.contains(*hash));
  auto read = blobs.read(*hash);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(*read, bytes);

  auto empty = blobs.put({});
  ASSERT_TRUE(empty.ok());
  auto read_empty = blobs.read(*empty);
  ASSERT_TRUE(read_empty.ok()) << read_empty.error().message;
  EXPECT_TRUE(read_empty->empty());
}

TEST(BlobStore, PutOfExistingBlobDoesNotRewriteIt) {
  BlobStore blobs(rigport_test::makeTempDir("blobs"));
  auto first = blobs.put(bytesOf("same content"));
  ASSERT_TRUE(first.ok());
  struct stat before{};
  ASSERT_EQ(::stat(blobs.pathOf(*first).c_str(), &before), 0);
  auto second = blobs.put(bytesOf("same content"));
  ASSERT_TRUE(second.ok());
  EXPECT_EQ(*first, *second);
  struct stat after{};
  ASSERT_EQ(::stat(blobs.pathOf(*first).c_str(), &after), 0);
  EXPECT_EQ(before.st_ino, after.st_ino) << "an existing blob was replaced";
  EXPECT_TRUE(fs::is_empty(blobs.root() / "tmp")) << "temporary file left behind";
}

TEST(BlobStore, ReadRejectsCorruptedOrTruncatedBlob) {
  BlobStore blobs(rigport_test::makeTempDir("blobs"));
  auto hash = blobs.put(bytesOf("a rig file that will be damaged on disk"));
  ASSERT_TRUE(hash.ok());
  const fs::path path = blobs.pathOf(*hash);
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(5);
    char c = 0;
    f.read(&c, 1);
    c = static_cast<char>(c ^ 0x01);
    f.seekp(5);
    f.write(&c, 1);
  }
  auto corrupted = blobs.read(*hash);
  ASSERT_FALSE(corrupted.ok()) << "a corrupted blob was served";
  EXPECT_EQ(corrupted.error().code, core::ErrorCode::kIo);
  EXPECT_NE(corrupted.error().message.find(path.string()), std::string::npos) << corrupted.error().message;

  fs::resize_file(path, 3);
  auto truncated = blobs.read(*hash);
  ASSERT_FALSE(truncated.ok()) << "a truncated blob was served";
  EXPECT_EQ(truncated.error().code, core::ErrorCode::kIo);

  // Putting the same bytes again repairs a blob whose size is wrong.
  ASSERT_TRUE(blobs.put(bytesOf("a rig file that will be damaged on disk")).ok());
  EXPECT_TRUE(blobs.read(*hash).ok());
}

TEST(BlobStore, ReadRejectsMissingBlobAndMalformedHash) {
  BlobStore blobs(rigport_test::makeTempDir("blobs"));
  auto missing = blobs.read(std::string(64, 'f'));
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, core::ErrorCode::kIo);
  EXPECT_NE(missing.error().message.find(blobs.pathOf(std::string(64, 'f')).string()), std::string::npos);
  auto traversal = blobs.read("../../etc/passwd");
  ASSERT_FALSE(traversal.ok());
  EXPECT_EQ(traversal.error().code, core::ErrorCode::kInvalidArgument);
  EXPECT_FALSE(blobs.contains("../../etc/passwd"));
  EXPECT_FALSE(blobs.contains(std::string(64, 'A')));
}

TEST(BlobStore, AdoptMovesFileUnderItsHashAndConsumesDuplicates) {
  const fs::path dir = rigport_test::makeTempDir("adopt");
  BlobStore blobs(dir / "blobs");
  std::mt19937 rng(7);
  const auto bytes = randomBytes(200000, rng);
  const fs::path upload = dir / "upload.part";
  std::ofstream(upload, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());

  auto hash = blobs.adopt(upload);
  ASSERT_TRUE(hash.ok()) << hash.error().message;
  EXPECT_EQ(*hash, api::sha256Hex(bytes));
  EXPECT_FALSE(fs::exists(upload));
  auto read = blobs.read(*hash);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(*read, bytes);

  // The same content again: the store keeps its copy and deletes the source.
  std::ofstream(upload, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  auto again = blobs.adopt(upload);
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(*again, *hash);
  EXPECT_FALSE(fs::exists(upload));

  auto missing = blobs.adopt(dir / "nope");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find((dir / "nope").string()), std::string::npos);
}

TEST(BlobStore, BlobIsNeverVisibleHalfWritten) {
  // A reader polling the final path while a large blob is written must see
  // either nothing or the whole, verified blob (the rename publishes it).
  BlobStore blobs(rigport_test::makeTempDir("visible"));
  std::mt19937 rng(3);
  const auto bytes = randomBytes(16u << 20, rng);
  const std::string hash = api::sha256Hex(bytes);
  std::atomic<bool> done{false};
  std::atomic<int> polls{0}, bad{0};
  std::string first_error;
  std::thread reader([&] {
    while (!done.load()) {
      ++polls;
      struct stat st{};
      if (::stat(blobs.pathOf(hash).c_str(), &st) == 0 && static_cast<std::size_t>(st.st_size) != bytes.size()) {
        if (bad++ == 0) first_error = "final path has " + std::to_string(st.st_size) + " bytes";
      }
    }
  });
  auto put = blobs.put(bytes);
  done = true;
  reader.join();
  ASSERT_TRUE(put.ok()) << put.error().message;
  EXPECT_EQ(*put, hash);
  EXPECT_GT(polls.load(), 0);
  EXPECT_EQ(bad.load(), 0) << first_error;
  EXPECT_TRUE(blobs.read(hash).ok());
}

TEST(BlobStore, RemoveTemporariesDeletesLeftoversButNotBlobs) {
  BlobStore blobs(rigport_test::makeTempDir("blobs"));
  auto hash = blobs.put(bytesOf("keep me"));
  ASSERT_TRUE(hash.ok());
  std::ofstream(blobs.root() / "tmp" / "0123.part") << "half a blob";
  std::ofstream(blobs.root() / "tmp" / "4567.part") << "another half";
  // A shared blob directory: another replica's write in flight is young; a
  // leftover is old.
  fs::last_write_time(blobs.root() / "tmp" / "0123.part", fs::file_time_type::clock::now() - std::chrono::hours(2));
  blobs.removeTemporaries(std::chrono::hours(1));
  EXPECT_FALSE(fs::exists(blobs.root() / "tmp" / "0123.part")) << "a leftover two hours old stays";
  EXPECT_TRUE(fs::exists(blobs.root() / "tmp" / "4567.part")) << "a write in flight was removed";
  blobs.removeTemporaries(std::chrono::seconds(0));
  EXPECT_TRUE(fs::is_empty(blobs.root() / "tmp"));
  EXPECT_TRUE(blobs.read(*hash).ok());

  blobs.remove(*hash);
  EXPECT_FALSE(blobs.contains(*hash));
  BlobStore fresh(rigport_test::makeTempDir("fresh"));
  fresh.removeTemporaries(std::chrono::seconds(0));  // no tmp directory yet: a no-op
}

}  // namespace
