// The one text rule (text.h) and the secrets helpers of the daemon.
#include "frictiond/server/text.h"

#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <sys/stat.h>

#include "frictiond/server/daemon.h"
#include "frictiond/server/request_error.h"

namespace frictiond {
namespace {

TEST(TextTest, Utf8Validity) {
  EXPECT_TRUE(IsValidUtf8(""));
  EXPECT_TRUE(IsValidUtf8("plain ascii"));
  EXPECT_TRUE(IsValidUtf8("caf\xC3\xA9 \xE2\x9C\x93 \xF0\x9F\x98\x80"));
  EXPECT_FALSE(IsValidUtf8("\xC3"));              // cut sequence
  EXPECT_FALSE(IsValidUtf8("\xFF"));              // never valid
  EXPECT_FALSE(IsValidUtf8("\xC0\xAF"));          // overlong '/'
  EXPECT_FALSE(IsValidUtf8("\xE0\x80\xAF"));      // overlong
  EXPECT_FALSE(IsValidUtf8("\xED\xA0\x80"));      // surrogate U+D800
  EXPECT_FALSE(IsValidUtf8("\xF4\x90\x80\x80"));  // above U+10FFFF
  EXPECT_FALSE(IsValidUtf8("a\x80"));             // lone continuation
}

TEST(TextTest, CheckTextNamesTheFieldAndRule) {
  EXPECT_NO_THROW(CheckText("robot-1 \xC3\xA9", "robot"));
  try {
    CheckText("ab\xC3", "robot");
    FAIL() << "no throw";
  } catch (const RequestError& e) {
    EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(e.field(), "robot");
    EXPECT_NE(std::string(e.what()).find("invalid UTF-8 at byte 2"),
              std::string::npos)
        << e.what();
    EXPECT_TRUE(IsValidUtf8(e.what()));
  }
  try {
    CheckText(std::string(300, 'x'), "name", 256);
    FAIL() << "no throw";
  } catch (const RequestError& e) {
    EXPECT_NE(std::string(e.what()).find("at most 256"), std::string::npos);
  }
  EXPECT_THROW(CheckText("a\nb", "robot"), RequestError);
  EXPECT_THROW(CheckText(std::string("a\0b", 3), "robot"), RequestError);
  EXPECT_NO_THROW(CheckText("a\tb", "robot"));
}

TEST(TextTest, ShownTextIsAlwaysValidAndShort) {
  EXPECT_EQ(ShownText("abc"), "abc");
  EXPECT_EQ(ShownText("a\xFF\x01z"), "a??z");
  EXPECT_EQ(ShownText(std::string(50, 'x'), 10), std::string(10, 'x') + "...");
  // Cut at a character boundary, never inside a sequence.
  const std::string e_acute = "\xC3\xA9";
  std::string many;
  for (int i = 0; i < 20; ++i) many += e_acute;
  const std::string shown = ShownText(many, 5);
  EXPECT_TRUE(IsValidUtf8(shown));
  EXPECT_EQ(shown.substr(0, 10), many.substr(0, 10));
}

TEST(SecretsTest, DatabaseUrlsAreLoggedWithoutPasswords) {
  EXPECT_EQ(RedactDbUrl("postgresql://fd:s3cret@db.local:5432/frictiond"),
            "postgresql://fd:***@db.local:5432/frictiond");
  EXPECT_EQ(RedactDbUrl("postgres://fd@db/x?password=s3cret&sslmode=require"),
            "postgres://fd@db/x?password=***&sslmode=require");
  EXPECT_EQ(RedactDbUrl("host=db user=fd password=s3cret dbname=x"),
            "host=db user=fd password=*** dbname=x");
  EXPECT_EQ(RedactDbUrl("postgresql://fd@db/x"), "postgresql://fd@db/x");
  EXPECT_EQ(RedactDbUrl("/var/lib/frictiond/lib.db"),
            "/var/lib/frictiond/lib.db");
}

TEST(SecretsTest, BootstrapSecretFromFileAndDatabaseFileIsPrivate) {
  char tmpl[] = "/tmp/frictiond-secrets-XXXXXX";
  ASSERT_NE(mkdtemp(tmpl), nullptr);
  const std::string dir = tmpl;
  DaemonConfig c;
  c.db = dir + "/lib.db";
  c.port = 0;
  c.data_dir = "none";
  c.threads = 1;
  c.bootstrap_token_file = dir + "/token";
  { std::ofstream(c.bootstrap_token_file) << "from-a-file-0123456789abcdef\n"; }
  EXPECT_EQ(c.BootstrapSecret(), "from-a-file-0123456789abcdef");
  {
    Daemon d(c);
    d.Start();
    HttpRequest r;
    r.method = "GET";
    r.path = "/v1/tokens";  // operator only
    r.remote_addr = "127.0.0.1";
    r.headers.emplace("Authorization", "Bearer from-a-file-0123456789abcdef");
    EXPECT_EQ(d.http().Dispatch(r).status, 200)
        << "the operator token was not created from the file";
    d.Stop();
  }
  struct stat st {};
  ASSERT_EQ(::stat(c.db.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u) << std::oct << (st.st_mode & 0777);
  c.bootstrap_token_file = dir + "/missing";
  EXPECT_THROW(c.Validate(), std::invalid_argument);
  std::remove((dir + "/lib.db").c_str());
  std::remove((dir + "/lib.db-wal").c_str());
  std::remove((dir + "/lib.db-shm").c_str());
  std::remove((dir + "/token").c_str());
  ::rmdir(dir.c_str());
}

}  // namespace
}  // namespace frictiond
