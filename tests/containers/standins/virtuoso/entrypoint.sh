#!/bin/sh
# Stand-in for the official Virtuoso image's entrypoint (container tests only). Like it:
# - the database lives in /database (the volume), its virtuoso.ini too;
# - VIRT_<Section>_<Key>=value variables set `Key = value` in [Section] of virtuoso.ini at every start;
# - DBA_PASSWORD becomes the dba password when the database is created, and only then.
set -eu
cd /database
[ -f virtuoso.ini ] || cp /opt/virtuoso/virtuoso.ini virtuoso.ini

set_ini() {  # section key value
  awk -v section="[$1]" -v key="$2" -v value="$3" '
    function put() { print key " = " value; done = 1 }
    /^\[/ { if (inside && !done) put(); inside = ($0 == section) }
    inside && !done && $0 ~ "^[ \t]*" key "[ \t]*=" { put(); next }
    { print }
    END { if (!done) { if (!inside) print section; put() } }
  ' virtuoso.ini > virtuoso.ini.new
  mv virtuoso.ini.new virtuoso.ini
}
env | sed -n 's/^VIRT_\([A-Za-z]*\)_\([A-Za-z_]*\)=\(.*\)$/\1 \2 \3/p' | while read -r section key value; do
  set_ini "$section" "$key" "$value"
done

if [ ! -f virtuoso.db ]; then
  virtuoso-t +configfile virtuoso.ini +wait
  password=$(printf '%s' "${DBA_PASSWORD:-dba}" | sed "s/'/''/g")
  isql 1111 dba dba "exec=user_set_password('dba', '$password'); checkpoint;" > /dev/null
  isql 1111 dba "${DBA_PASSWORD:-dba}" "exec=shutdown();" > /dev/null 2>&1 || true
  while [ -f virtuoso.lck ]; do sleep 0.2; done
  echo "virtuoso stand-in: database created, dba password set from DBA_PASSWORD"
fi
exec virtuoso-t +configfile virtuoso.ini +foreground
