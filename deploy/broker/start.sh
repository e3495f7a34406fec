#!/bin/sh
# The broker's container (docker-compose.yml, service mosquitto): Debian's mosquitto installed on first start; a CA of
# this deployment's own and the broker's certificate signed by it, made here on first start and never committed; the
# dynamic security plugin's file with the admin identity; then Mosquitto in the foreground. Whatever exists is kept,
# so a restart changes nothing. The CA's certificate (not its key) goes to $CA_OUT for the API instances and bridges,
# which check the broker against it.
#   QUASITUNE_BROKER_HOST             the name legs connect to (in the certificate; localhost and 127.0.0.1 always are)
#   QUASITUNE_BROKER_ADMIN_USERNAME, QUASITUNE_BROKER_ADMIN_PASSWORD   the admin identity (first start only)
#   QUASITUNE_BROKER_DATA, QUASITUNE_BROKER_CA_OUT, QUASITUNE_BROKER_PORT, QUASITUNE_BROKER_ADDRESS   where and how
set -eu
HERE=$(cd "$(dirname "$0")" && pwd)
DATA=${QUASITUNE_BROKER_DATA:-/var/lib/quasitune-broker}
CA_OUT=${QUASITUNE_BROKER_CA_OUT:-/ca}
HOST=${QUASITUNE_BROKER_HOST:-localhost}
if ! command -v mosquitto >/dev/null 2>&1 && [ ! -x /usr/sbin/mosquitto ]; then
  apt-get update -q && apt-get install -y -q --no-install-recommends mosquitto mosquitto-clients openssl
fi
mkdir -p "$DATA/tls" "$CA_OUT"
if [ ! -f "$DATA/tls/server.crt" ]; then
  cd "$DATA/tls"
  openssl req -x509 -newkey rsa:3072 -nodes -days 3650 -subj "/CN=QuasiTune broker CA" -keyout ca.key -out ca.crt \
    2>/dev/null
  openssl req -newkey rsa:3072 -nodes -subj "/CN=$HOST" -keyout server.key -out server.csr 2>/dev/null
  printf 'subjectAltName=DNS:%s,DNS:localhost,IP:127.0.0.1\n' "$HOST" > san.ext
  openssl x509 -req -in server.csr -CA ca.crt -CAkey ca.key -CAcreateserial -days 825 -extfile san.ext \
    -out server.crt 2>/dev/null
  rm -f server.csr san.ext
  chmod 600 ca.key server.key
  cd - >/dev/null
fi
if [ ! -f "$DATA/dynsec.json" ]; then
  mosquitto_ctrl dynsec init "$DATA/dynsec.json" "$QUASITUNE_BROKER_ADMIN_USERNAME" "$QUASITUNE_BROKER_ADMIN_PASSWORD" \
    >/dev/null
fi
cp "$DATA/tls/ca.crt" "$CA_OUT/ca.crt"
if [ "$(id -u)" = 0 ]; then chown -R mosquitto:mosquitto "$DATA"; fi   # Mosquitto drops root for this user
PLUGIN=$(ls /usr/lib/*/mosquitto_dynamic_security.so /usr/lib/mosquitto_dynamic_security.so 2>/dev/null | head -n 1)
sed -e "s#@PLUGIN@#$PLUGIN#" -e "s#@DATA@#$DATA#g" -e "s#@PORT@#${QUASITUNE_BROKER_PORT:-8883}#" \
    -e "s#@ADDRESS@#${QUASITUNE_BROKER_ADDRESS:-}#" "$HERE/mosquitto.conf" > "$DATA/mosquitto.conf"
exec /usr/sbin/mosquitto -c "$DATA/mosquitto.conf"
