// Clients that hold connections open without finishing their requests
// (slowloris heads, POSTs without a length, uploads trickling a byte at a
// time) must not take the service from anybody else: they wait at the gate
// without a thread, are answered or closed when their time is up, and upload
// slots are counted per tenant and per client address. Real sockets on
// loopback against the real service.
#include <gtest/gtest.h>

#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <thread>

#include "tests/server/service_fixture.h"
#include "tests/test_support.h"

namespace rigport_test {
namespace {

using Clock = std::chrono::steady_clock;

// A raw TCP connection to the service, for requests httplib::Client would
// never send.
class RawConnection {
 public:
  explicit RawConnection(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
    timeval timeout{10, 0};  // no answer in 10 s is a failure, not a hang
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  }
  ~RawConnection() {
    if (fd_ >= 0) ::close(fd_);
  }
  RawConnection(const RawConnection&) = delete;
  RawConnection& operator=(const RawConnection&) = delete;
  bool connected() const { return connected_; }
  bool send(const std::string& bytes) const {
    return ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(bytes.size());
  }
  // Everything until the peer closes (or 10 s without a byte: closedByPeer() false).
  std::string readUntilClosed() {
    std::string out;
    char buf[4096];
    for (;;) {
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) {
        closed_by_peer_ = n == 0 || errno == ECONNRESET;
        return out;
      }
      out.append(buf, static_cast<std::size_t>(n));
    }
  }
  bool closedByPeer() const { return closed_by_peer_; }
  // One response whose body is `Content-Length` long (keep-alive).
  std::string readResponse() const {
    std::string out;
    char buf[4096];
    for (;;) {
      const std::size_t head_end = out.find("\r\n\r\n");
      if (head_end != std::string::npos) {
        const std::size_t at = out.find("Content-Length: ");
        const std::size_t length = at == std::string::npos ? 0 : std::stoul(out.substr(at + 16));
        if (out.size() >= head_end + 4 + length) return out;
      }
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) return out;
      out.append(buf, static_cast<std::size_t>(n));
    }
  }

 private:
  int fd_ = -1;
  bool connected_ = false;
  bool closed_by_peer_ = false;
};

int statusOf(const std::string& response) {
  if (response.rfind("HTTP/1.1 ", 0) != 0 || response.size() < 12) return 0;
  return std::stoi(response.substr(9, 3));
}

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

TEST(HostileClients, HundredSlowHeadsLeaveProbesAndJobsServed) {
  const auto dir = makeTempDir("slowloris");
  const TransferFiles files = writeTransferFiles(dir);
  server::ServerConfig config = testConfig(dir / "data");
  config.head_timeout_s = 1.5;
  InProcessService service(config);

  // 100 connections that send half a head and then nothing more, and 32
  // POSTs without a length that never close.
  std::vector<std::unique_ptr<RawConnection>> slow;
  for (int i = 0; i < 100; ++i) {
    slow.push_back(std::make_unique<RawConnection>(service.port()));
    ASSERT_TRUE(slow.back()->connected());
    ASSERT_TRUE(slow.back()->send("GET /healthz HTTP/1.1\r\nHost: rigport\r\nX-Slow: "));
  }
  std::vector<std::unique_ptr<RawConnection>> no_length;
  for (int i = 0; i < 32; ++i) {
    no_length.push_back(std::make_unique<RawConnection>(service.port()));
    ASSERT_TRUE(no_length.back()->send("POST /v1/jobs/0123456789abcdef0123456789abcdef:cancel HTTP/1.1\r\nHost: rigport\r\n\r\n"));
  }

  auto client = service.client();
  const auto probe_start = Clock::now();
  const Reply health = get(*client, "/healthz");
  const double probe_s = secondsSince(probe_start);
  EXPECT_EQ(health.status, 200) << health.raw;
  const auto job_start = Clock::now();
  const Reply rig = uploadRig(*client, files);
  ASSERT_EQ(rig.status, 201) << rig.raw;
  const Reply job = submitTransfer(*client, rig.body["id"], files);
  ASSERT_EQ(job.status, 202) << job.raw;
  EXPECT_EQ(waitForJob(*client, job.body["id"])["status"], "succeeded");
  const double job_s = secondsSince(job_start);
  RecordProperty("healthz_ms", static_cast<int>(probe_s * 1000));
  RecordProperty("job_ms", static_cast<int>(job_s * 1000));
  std::printf("with 100 slow heads and 32 length-less POSTs open: /healthz %.1f ms, upload+job+wait %.1f ms\n",
              probe_s * 1000, job_s * 1000);

  // A POST without a length has an empty body (RFC 9112): answered at once.
  for (const auto& c : no_length) {
    const std::string response = c->readResponse();
    EXPECT_EQ(statusOf(response), 404) << response;  // no such job; read, not waited on
  }
  // The slow heads are answered 408 when their time is up (or were closed to
  // make room for newer connections of the same address).
  int timed_out = 0, closed = 0;
  for (const auto& c : slow) {
    const std::string response = c->readUntilClosed();
    if (statusOf(response) == 408) {
      ++timed_out;
      EXPECT_NE(response.find("urn:rigport:problem:request-timeout"), std::string::npos) << response;
    } else {
      EXPECT_EQ(response, "") << "a slow head got an answer other than 408";
      ++closed;
    }
  }
  EXPECT_EQ(timed_out + closed, 100);
}

TEST(HostileClients, RequestsTheGateJudgesAreAnsweredWithoutAThread) {
  const auto dir = makeTempDir("gate_answers");
  server::ServerConfig config = testConfig(dir / "data");
  config.head_timeout_s = 0.5;
  InProcessService service(config);
  const auto ask = [&](const std::string& request) {
    RawConnection c(service.port());
    EXPECT_TRUE(c.send(request));
    return c.readUntilClosed();
  };
  const std::string chunked = ask(
      "POST /v1/jobs/0123456789abcdef0123456789abcdef:cancel HTTP/1.1\r\nHost: r\r\nTransfer-Encoding: chunked\r\n\r\n5\r\nhello\r\n");
  EXPECT_EQ(statusOf(chunked), 411) << chunked;
  EXPECT_NE(chunked.find("urn:rigport:problem:length-required"), std::string::npos);
  const std::string big = ask("DELETE /v1/rigs/" + std::string(64, 'a') + " HTTP/1.1\r\nHost: r\r\nContent-Length: 10000000\r\n\r\n");
  EXPECT_EQ(statusOf(big), 413) << big;
  const std::string smuggled =
      ask("POST /v1/jobs HTTP/1.1\r\nHost: r\r\nContent-Length: 5\r\nTransfer-Encoding: chunked\r\n\r\nhello");
  EXPECT_EQ(statusOf(smuggled), 400) << smuggled;
  const std::string huge_head = ask("GET /healthz HTTP/1.1\r\nHost: r\r\nX-Big: " + std::string(20000, 'x') + "\r\n\r\n");
  EXPECT_EQ(statusOf(huge_head), 431) << huge_head;
  const std::string nul = ask(std::string("GET /healthz HTTP/1.1\r\nHost: r\r\nX-A: a\0b\r\n\r\n", 44));
  EXPECT_EQ(statusOf(nul), 400) << nul;
  EXPECT_NE(nul.find("NUL"), std::string::npos) << nul;
  const std::string bare_cr = ask("GET /healthz HTTP/1.1\r\nHost: r\rX-A: b\r\n\r\n");
  EXPECT_EQ(statusOf(bare_cr), 400) << bare_cr;
  const std::string not_http = ask("HELLO\r\n\r\n");
  EXPECT_EQ(statusOf(not_http), 400) << not_http;
  const std::string slow_head = ask("GET /healthz HTTP/1.1\r\nHost: r\r\n");  // and then nothing
  EXPECT_EQ(statusOf(slow_head), 408) << slow_head;
  EXPECT_NE(slow_head.find("urn:rigport:problem:request-timeout"), std::string::npos) << slow_head;

  // A kept-alive connection serves one request after another.
  RawConnection keep(service.port());
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(keep.send("GET /healthz HTTP/1.1\r\nHost: r\r\n\r\n"));
    const std::string response = keep.readResponse();
    EXPECT_EQ(statusOf(response), 200) << "request " << i << ": " << response;
  }
  // Two requests in one write (pipelined): both answered, in order.
  RawConnection pipelined(service.port());
  ASSERT_TRUE(pipelined.send("GET /healthz HTTP/1.1\r\nHost: r\r\n\r\nGET /nope HTTP/1.1\r\nHost: r\r\nConnection: close\r\n\r\n"));
  const std::string both = pipelined.readUntilClosed();
  EXPECT_EQ(statusOf(both), 200) << both;
  EXPECT_NE(both.find("HTTP/1.1 404"), std::string::npos) << both;
}

TEST(HostileClients, StalledTlsHandshakesHoldNoThreadAndAreClosed) {
  const auto dir = makeTempDir("tls_stall");
  const TransferFiles files = writeTransferFiles(dir);
  const TlsFiles tls = writeSelfSignedCertificate(dir / "tls");
  server::ServerConfig config = testConfig(dir / "data");
  config.tls_certificate_file = tls.certificate;
  config.tls_private_key_file = tls.private_key;
  config.head_timeout_s = 1.5;
  config.http_threads = 16;  // fewer threads than stalled connections
  config.max_concurrent_uploads = 6;
  config.max_concurrent_waits = 6;
  InProcessService service(config);

  // 40 connections that send nothing, 40 that stop inside their ClientHello
  // (a TLS record header promising 512 bytes, then 6 of them), 20 that
  // speak plain HTTP to the HTTPS port.
  std::vector<std::unique_ptr<RawConnection>> stalled, plain;
  for (int i = 0; i < 80; ++i) {
    stalled.push_back(std::make_unique<RawConnection>(service.port()));
    ASSERT_TRUE(stalled.back()->connected());
    if (i % 2) {
      ASSERT_TRUE(stalled.back()->send(std::string("\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03", 11)));
    }
  }
  for (int i = 0; i < 20; ++i) {
    plain.push_back(std::make_unique<RawConnection>(service.port()));
    ASSERT_TRUE(plain.back()->send("GET /healthz HTTP/1.1\r\nHost: rigport\r\n\r\n"));
  }

  auto client = service.client();
  EXPECT_EQ(get(*client, "/healthz").status, 200);
  const Reply rig = uploadRig(*client, files);
  ASSERT_EQ(rig.status, 201) << rig.raw;
  const Reply job = submitTransfer(*client, rig.body["id"], files);
  ASSERT_EQ(job.status, 202) << job.raw;
  EXPECT_EQ(waitForJob(*client, job.body["id"])["status"], "succeeded");

  // Plain HTTP gets no HTTP answer (at most a TLS alert) and is closed.
  for (const auto& c : plain) {
    const std::string response = c->readUntilClosed();
    EXPECT_TRUE(c->closedByPeer());
    EXPECT_NE(response.rfind("HTTP/", 0), 0u) << response;
  }
  // The stalled handshakes are closed when the head's time is up.
  for (const auto& c : stalled) {
    const std::string response = c->readUntilClosed();
    EXPECT_TRUE(c->closedByPeer()) << "a stalled handshake was left open";
    EXPECT_NE(response.rfind("HTTP/", 0), 0u) << response;
  }
  EXPECT_EQ(get(*client, "/healthz").status, 200);
}

TEST(HostileClients, ASecondServiceCannotShareTheListeningPort) {
  const auto dir = makeTempDir("port_taken");
  InProcessService first(testConfig(dir / "first"));
  server::ServerConfig config = testConfig(dir / "second");
  config.port = first.port();
  auto second = server::Service::create(config, server::ApiKeys::disabled(), nullptr);
  ASSERT_TRUE(second) << second.error().message;
  const auto started = (*second)->start();
  ASSERT_FALSE(started) << "a second service listens on port " << first.port() << " too";
  EXPECT_NE(started.error().message.find(std::to_string(first.port())), std::string::npos) << started.error().message;
  EXPECT_EQ(get(*first.client(), "/healthz").status, 200);
}

// A multipart upload whose head promises `length` bytes, then sends only the
// start of its body.
std::unique_ptr<RawConnection> trickleUpload(int port, const std::string& key) {
  auto c = std::make_unique<RawConnection>(port);
  const std::string boundary = "rigportboundary";
  EXPECT_TRUE(c->send("POST /v1/rigs HTTP/1.1\r\nHost: r\r\nAuthorization: Bearer " + key +
                      "\r\nContent-Type: multipart/form-data; boundary=" + boundary +
                      "\r\nContent-Length: 1000000\r\n\r\n--" + boundary +
                      "\r\nContent-Disposition: form-data; name=\"rig\"; filename=\"rig.glb\"\r\n\r\nglTF"));
  return c;
}

TEST(HostileClients, TricklingUploadsBlockOnlyTheirOwnTenantAndTimeOut) {
  const auto dir = makeTempDir("trickle");
  const TransferFiles files = writeTransferFiles(dir);
  server::ServerConfig config = testConfig(dir / "data");
  config.upload_time_limit_s = 3.0;
  config.max_uploads_per_tenant = 4;  // below the per-address 10: another tenant on the same host still gets a slot
  auto keys = server::ApiKeys::load({}, "key-alice:alice,key-bob:bob");
  ASSERT_TRUE(keys);
  InProcessService service(config, std::move(*keys));

  std::vector<std::unique_ptr<RawConnection>> trickling;
  for (int i = 0; i < config.max_uploads_per_tenant; ++i) trickling.push_back(trickleUpload(service.port(), "key-alice"));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // they hold their slots

  auto alice = service.client("key-alice");
  const Reply refused = uploadRig(*alice, files);
  EXPECT_EQ(refused.status, 429) << refused.raw;
  EXPECT_EQ(refused.body["type"], "urn:rigport:problem:too-many-uploads");
  EXPECT_FALSE(refused.retry_after.empty());
  auto bob = service.client("key-bob");
  const Reply accepted = uploadRig(*bob, files);
  EXPECT_EQ(accepted.status, 201) << "another tenant must not be blocked: " << accepted.raw;

  // Past the upload time limit the trickling uploads are cut off and their
  // slots come back.
  for (const auto& c : trickling) c->readUntilClosed();
  const Reply later = uploadRig(*alice, files);
  EXPECT_EQ(later.status, 201) << later.raw;
  const Reply listing = get(*alice, "/v1/rigs");
  EXPECT_EQ(listing.body["items"].size(), 1u) << "a cut-off upload must store nothing";
}

}  // namespace
}  // namespace rigport_test
