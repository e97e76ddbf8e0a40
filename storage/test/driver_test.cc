// The connection interface (src/connection.h) behaves the same on every
// driver: $N parameters (repeated, out of order, not inside literals),
// typed cells, bytes with NUL, affected rows of writes only, rollback when
// a write throws. The store logic (sql_store.cc) relies on each of these.
#include <atomic>
#include <cstdio>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "frictiond/storage/store.h"
#include "frictiond/testing/pg_server.h"

#include "connection.h"

namespace frictiond {
namespace {

using internal::Connection;
using internal::Driver;
using internal::Params;
using internal::Rows;

#ifdef FRICTIOND_HAVE_POSTGRES
testing::PgServer& SharedPg() {
  static std::mutex mu;
  static std::unique_ptr<testing::PgServer> pg;
  std::lock_guard<std::mutex> lock(mu);
  if (!pg) {
    auto p = std::make_unique<testing::PgServer>();
    p->Start();
    pg = std::move(p);
  }
  return *pg;
}
#endif

class DriverTest : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == "postgresql") {
#ifdef FRICTIOND_HAVE_POSTGRES
      if (!testing::PgServer::RequireOrSkip()) GTEST_SKIP() << "no PostgreSQL";
      static std::atomic<int> n{0};
      driver_ = internal::OpenPostgresDriver(SharedPg().CreateDatabase(
          "d" + std::to_string(::getpid()) + "_" + std::to_string(++n)));
#else
      GTEST_SKIP() << "built without PostgreSQL";
#endif
    } else {
      driver_ = internal::OpenSqliteDriver(":memory:");
    }
    const std::string script =
        std::string("CREATE TABLE t(id ") +
        driver_->dialect().serial_primary_key +
        ", name TEXT NOT NULL, n BIGINT NOT NULL, data " +
        driver_->dialect().bytes_type + " NOT NULL)";
    driver_->Write([&](Connection& c) { c.ExecuteScript(script); });
  }
  std::unique_ptr<Driver> driver_;
};

TEST_P(DriverTest, ParametersRepeatAndMayComeOutOfOrder) {
  driver_->Read([](Connection& c) {
    Rows r =
        c.Execute("SELECT $2 || $1 || $2, '$1 stays', CAST($3 AS BIGINT) + $3",
                  Params().Text("b").Text("a").Int(20));
    ASSERT_EQ(r.size(), 1);
    EXPECT_EQ(r.Take(0, 0), "aba");
    EXPECT_EQ(r.Take(0, 1), "$1 stays");
    EXPECT_EQ(r.Int(0, 2), 40);
  });
}

TEST_P(DriverTest, InsertReturningBytesAndAffectedRows) {
  const std::string bytes("a\0b\xff", 4);
  const std::string name = "it's";  // borrowed, not copied
  std::int64_t id = 0;
  driver_->Write([&](Connection& c) {
    Rows r =
        c.Execute("INSERT INTO t(name,n,data) VALUES($1,$2,$3) RETURNING id, n",
                  Params().Text(name).Int(-7000000000).Bytes(bytes));
    ASSERT_EQ(r.size(), 1);
    id = r.Int(0, 0);
    EXPECT_EQ(r.Int(0, 1), -7000000000);
    EXPECT_EQ(r.affected(), 1);
  });
  EXPECT_GT(id, 0);
  driver_->Read([&](Connection& c) {
    Rows r = c.Execute("SELECT name, data, n < 0 FROM t WHERE id=$1",
                       Params().Int(id));
    ASSERT_EQ(r.size(), 1);
    EXPECT_EQ(r.Take(0, 0), name);
    EXPECT_EQ(r.Take(0, 1), bytes);
    EXPECT_EQ(r.Int(0, 2), 1);   // a boolean is the integer 1
    EXPECT_EQ(r.affected(), 0);  // a SELECT changes nothing
    EXPECT_THROW(r.Int(0, 0), std::runtime_error);  // text is not an integer
  });
  driver_->Write([](Connection& c) {
    EXPECT_EQ(c.Execute("UPDATE t SET n=n+1").affected(), 1);
    EXPECT_EQ(c.Execute("UPDATE t SET n=n+1 WHERE id<0").affected(), 0);
  });
}

TEST_P(DriverTest, ThrowingWriteIsRolledBack) {
  EXPECT_THROW(driver_->Write([](Connection& c) {
    c.Execute("INSERT INTO t(name,n,data) VALUES('x',1,$1)",
              Params().Bytes(std::string("y")));
    throw std::runtime_error("refused");
  }),
               std::runtime_error);
  // A failing statement: the driver's error, and nothing stored either.
  try {
    driver_->Write([](Connection& c) {
      c.Execute("INSERT INTO t(name,n,data) VALUES('x',1,'y')");
      c.Execute("INSERT INTO missing_table VALUES(1)");
    });
    ADD_FAILURE() << "no error for a missing table";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(driver_->dialect().name, 0), 0u)
        << e.what();
  }
  driver_->Read([](Connection& c) {
    EXPECT_EQ(c.Execute("SELECT COUNT(*) FROM t").Int(0, 0), 0);
  });
}

// Writers running at once each get their own outcome: a write that
// returned is stored whole (both of its rows), a write that threw left
// nothing, and a write sees its own rows before it returns.
TEST_P(DriverTest, ConcurrentWritersKeepTheirOwnOutcome) {
  constexpr int kThreads = 6, kWrites = 40;
  std::vector<std::vector<int>> outcome(kThreads, std::vector<int>(kWrites));
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < kWrites; ++i) {
        const std::string name = "w" + std::to_string(t);
        try {
          driver_->Write([&](Connection& c) {
            for (int row = 0; row < 2; ++row)
              c.Execute("INSERT INTO t(name,n,data) VALUES($1,$2,'x')",
                        Params().Text(name).Int(i));
            EXPECT_EQ(c.Execute("SELECT COUNT(*) FROM t WHERE name=$1 AND n=$2",
                                Params().Text(name).Int(i))
                          .Int(0, 0),
                      2);
            if ((i + t) % 3 == 0) throw std::runtime_error("refused");
          });
          outcome[t][i] = 2;
        } catch (const std::runtime_error&) {
          outcome[t][i] = 0;
        }
      }
    });
  }
  for (auto& th : threads) th.join();
  driver_->Read([&](Connection& c) {
    for (int t = 0; t < kThreads; ++t) {
      for (int i = 0; i < kWrites; ++i) {
        EXPECT_EQ(outcome[t][i], (i + t) % 3 == 0 ? 0 : 2);
        EXPECT_EQ(c.Execute("SELECT COUNT(*) FROM t WHERE name=$1 AND n=$2",
                            Params().Text("w" + std::to_string(t)).Int(i))
                      .Int(0, 0),
                  outcome[t][i])
            << "writer " << t << " write " << i;
      }
    }
  });
}

// A database file another connection keeps locked (beyond the 5 s busy
// timeout) is an outage (StoreUnavailable: HTTP 503), not a bug, and the
// connection works again once the lock is gone.
TEST(SqliteDriver, LockedFileIsUnavailableThenRecovers) {
  const std::string path = ::testing::TempDir() + "frictiond_locked_" +
                           std::to_string(::getpid()) + ".db";
  std::remove(path.c_str());
  auto holder = internal::OpenSqliteDriver(path);
  auto other = internal::OpenSqliteDriver(path);
  holder->Write([](Connection& c) { c.ExecuteScript("CREATE TABLE t(x)"); });
  const auto write = [](Connection& c) {
    c.Execute("INSERT INTO t VALUES(1)");
  };
  holder->Write([&](Connection&) {
    EXPECT_THROW(other->Write(write), StoreUnavailable);
  });
  other->Write(write);
  other->Read([](Connection& c) {
    EXPECT_EQ(c.Execute("SELECT COUNT(*) FROM t").Int(0, 0), 1);
  });
  holder.reset();
  other.reset();
  for (const char* suffix : {"", "-wal", "-shm"})
    std::remove((path + suffix).c_str());
}

// Reads of a database file have connections of their own: a read while
// another thread's write transaction is open (its commit and fsync still to
// come) finishes at once and sees the last committed state, and sees the
// write once it commits.
TEST(SqliteDriver, ReadsDoNotWaitForAnOpenWrite) {
  const std::string path = ::testing::TempDir() + "frictiond_readers_" +
                           std::to_string(::getpid()) + ".db";
  std::remove(path.c_str());
  auto driver = internal::OpenSqliteDriver(path);
  driver->Write([](Connection& c) {
    c.ExecuteScript("CREATE TABLE t(x)");
    c.Execute("INSERT INTO t VALUES(1)");
  });
  const auto count = [&driver] {
    std::int64_t n = -1;
    driver->Read([&](Connection& c) {
      n = c.Execute("SELECT COUNT(*) FROM t").Int(0, 0);
    });
    return n;
  };
  driver->Write([&](Connection& c) {
    c.Execute("INSERT INTO t VALUES(2)");
    std::int64_t seen = -1;
    std::thread reader([&] { seen = count(); });
    reader.join();  // would deadlock if reads shared the write connection
    EXPECT_EQ(seen, 1);
  });
  EXPECT_EQ(count(), 2);
  // A read that throws leaves the driver usable.
  EXPECT_THROW(driver->Read([](Connection& c) {
    c.Execute("SELECT * FROM no_such_table");
  }),
               std::runtime_error);
  EXPECT_EQ(count(), 2);
  driver.reset();
  for (const char* suffix : {"", "-wal", "-shm"})
    std::remove((path + suffix).c_str());
}

INSTANTIATE_TEST_SUITE_P(Drivers,
                         DriverTest,
                         ::testing::Values("sqlite", "postgresql"));

}  // namespace
}  // namespace frictiond
