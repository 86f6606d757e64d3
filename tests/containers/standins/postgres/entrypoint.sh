#!/bin/sh
# Stand-in for the official PostgreSQL image's entrypoint (container tests only). Like it: a new data folder
# gets a cluster whose superuser is POSTGRES_USER with the password POSTGRES_PASSWORD, and a database
# POSTGRES_DB; connections over the network need that password; the server runs as the postgres user.
set -eu
as_postgres() { setpriv --reuid=postgres --regid=postgres --init-groups "$@"; }
chown postgres:postgres "$PGDATA"
if [ ! -s "$PGDATA/PG_VERSION" ]; then
  printf '%s\n' "$POSTGRES_PASSWORD" > /tmp/pwfile
  chown postgres /tmp/pwfile
  # UTF8, as the official image's locale gives it (initdb's default here, SQL_ASCII, hands clients bytes).
  as_postgres initdb -D "$PGDATA" -U "${POSTGRES_USER:-postgres}" --pwfile=/tmp/pwfile --encoding=UTF8 \
    --locale=C.UTF-8 --auth-local=trust --auth-host=scram-sha-256 > /dev/null
  rm /tmp/pwfile
  echo "host all all all scram-sha-256" >> "$PGDATA/pg_hba.conf"
  as_postgres pg_ctl -D "$PGDATA" -o "-c listen_addresses=''" -w start > /dev/null
  if [ "${POSTGRES_DB:-}" ] && [ "$POSTGRES_DB" != postgres ]; then
    as_postgres createdb -U "${POSTGRES_USER:-postgres}" "$POSTGRES_DB"
  fi
  as_postgres pg_ctl -D "$PGDATA" -m fast -w stop > /dev/null
  echo "postgres stand-in: cluster created for ${POSTGRES_USER:-postgres}"
fi
exec setpriv --reuid=postgres --regid=postgres --init-groups postgres -D "$PGDATA" -c listen_addresses='*'
