#!/usr/bin/env bash
# A throwaway PostgreSQL server for the history store's tests (test/test_history_store.py), on loopback only.
#
#   scripts/pg_test_server.sh start [DIR]   # initdb in DIR (default: a new temp dir), start on 127.0.0.1 and a free
#                                           # port; prints two lines: the SQLAlchemy URL, then DIR
#   scripts/pg_test_server.sh stop DIR      # stop the server started in DIR and remove DIR
#
# e.g.  read -r URL DIR < <(scripts/pg_test_server.sh start | paste -sd' ')
#       BEARING_ID_TEST_PG_URL=$URL .venv/bin/python -m pytest test/test_history_store.py
#       scripts/pg_test_server.sh stop "$DIR"
#
# Needs the Debian/Ubuntu server package (apt-get install postgresql; its binaries in /usr/lib/postgresql/<v>/bin)
# and psycopg in the venv.  PostgreSQL refuses to run as root: as root the server runs as PG_TEST_USER (default
# postgres, the package's system user).  The superuser bearing_id connects without a password (trust), which is
# acceptable only because the server listens on 127.0.0.1 and a socket in DIR, and lives as long as the test run.
set -euo pipefail

die() { echo "pg_test_server: $*" >&2; exit 1; }

bindir() {
    local d
    d=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1)
    [ -n "$d" ] && [ -x "$d/initdb" ] || die "no PostgreSQL server binaries in /usr/lib/postgresql/*/bin (apt-get install postgresql)"
    echo "$d"
}

as_owner() {    # run "$@" as the owner of the data directory (PG_TEST_USER when we are root)
    if [ "$(id -u)" -eq 0 ]; then
        runuser -u "${PG_TEST_USER:-postgres}" -- "$@"
    else
        "$@"
    fi
}

start() {
    local bin dir port
    bin=$(bindir)
    dir=${1:-$(mktemp -d -t bearing_id_pg.XXXXXX)}
    mkdir -p "$dir"
    if [ "$(id -u)" -eq 0 ]; then
        id "${PG_TEST_USER:-postgres}" >/dev/null 2>&1 || die "running as root and user ${PG_TEST_USER:-postgres} does not exist (set PG_TEST_USER)"
        chown "${PG_TEST_USER:-postgres}" "$dir"
    fi
    chmod 700 "$dir"
    as_owner "$bin/initdb" -D "$dir/data" -U bearing_id --auth=trust -E UTF8 --no-instructions >"$dir/initdb.log" 2>&1 \
        || die "initdb failed: $(tail -n 5 "$dir/initdb.log")"
    port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
    as_owner "$bin/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 60 \
        -o "-c listen_addresses=127.0.0.1 -p $port -k $dir -c fsync=off" start >/dev/null \
        || die "server did not start: $(tail -n 5 "$dir/server.log")"
    echo "$port" >"$dir/port"
    echo "postgresql+psycopg://bearing_id@127.0.0.1:$port/postgres"
    echo "$dir"
}

stop() {
    local dir=${1:-}
    [ -n "$dir" ] && [ -d "$dir/data" ] || die "usage: $0 stop DIR (the directory 'start' printed)"
    as_owner "$(bindir)/pg_ctl" -D "$dir/data" -m fast -w -t 60 stop >/dev/null || true
    rm -rf "$dir"
}

case "${1:-}" in
    start) shift; start "$@" ;;
    stop) shift; stop "$@" ;;
    *) die "usage: $0 start [DIR] | stop DIR" ;;
esac
