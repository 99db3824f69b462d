#!/bin/sh
# make-certs.sh DIR [CN ...] [--robot ROBOT_ID ...]: a private CA, the daemon's certificate and one client
# certificate per CN (DIR/CN.pem, DIR/CN.key), all with Debian's openssl. An existing CA in DIR is reused, so more
# clients (and robots) can be added later. Keys are written 0600. Days of validity: $POSED_TLS_DAYS (default 825).
# Every certificate is valid for 127.0.0.1 and localhost, plus $POSED_TLS_SAN (e.g. "IP:192.168.1.20,DNS:robot.local"),
# and good for both ends of a link (serverAuth, clientAuth), so a fleet's router is one more CN, made alone with its
# address: POSED_TLS_SAN="IP:192.168.1.10" make-certs.sh DIR posed-router (deploy/fleet/README.md).
#
# The daemon's certificate, two ways:
#   * without --robot: one shared certificate, CN posed-daemon (DIR/posed-daemon.pem, .key), made once and kept;
#     every robot holds it, so any robot can speak as any other on a fleet's router.
#   * --robot ROBOT_ID (repeatable, mixed freely with CNs): one certificate per robot, CN posed-daemon.ROBOT_ID, in
#     DIR/robots/ROBOT_ID/ under the names the shipped configs reference (posed-daemon.pem, posed-daemon.key, and
#     ca.pem): copy that folder's files to the robot's /etc/posed/tls/. ROBOT_ID is the robot's robot_id
#     (config.yaml): letters, digits, '_' and '-' only, at most 51 characters (a CN holds 64). The shared
#     certificate is then not made. deploy/fleet/make-acl.py writes the router's and the daemons' access control
#     that binds each such certificate to its own posed/ROBOT_ID/** (deploy/fleet/README.md, "One certificate
#     per robot").
set -eu
usage="usage: $0 DIR [CLIENT_CN ...] [--robot ROBOT_ID ...]"
[ $# -ge 1 ] || { echo "$usage" >&2; exit 64; }
command -v openssl >/dev/null || { echo "make-certs.sh: openssl is missing: apt-get install openssl" >&2; exit 69; }
dir=$1; shift
days=${POSED_TLS_DAYS:-825}
san="DNS:localhost,IP:127.0.0.1${POSED_TLS_SAN:+,$POSED_TLS_SAN}"
# check the arguments before anything is written: the robot ids as posed checks robot_id ([A-Za-z0-9_-]+)
robots=""; next_is_robot=""
for arg in "$@"; do
    if [ -n "$next_is_robot" ]; then
        case $arg in
            ''|*[!A-Za-z0-9_-]*)
                echo "make-certs.sh: --robot '$arg' is not a valid robot id: posed's robot_id is letters, digits," \
                     "'_' and '-' only (config.yaml robot_id); give that robot's robot_id" >&2; exit 64 ;;
        esac
        [ ${#arg} -le 51 ] || { echo "make-certs.sh: --robot '$arg' is too long for a certificate: a robot" \
            "id of at most 51 characters (CN posed-daemon.ROBOT_ID holds at most 64)" >&2; exit 64; }
        robots="$robots $arg"; next_is_robot=""
    elif [ "$arg" = "--robot" ]; then
        next_is_robot=1
    else
        case $arg in -*) echo "make-certs.sh: unknown option '$arg'; $usage" >&2; exit 64 ;; esac
    fi
done
[ -z "$next_is_robot" ] || { echo "make-certs.sh: --robot needs a robot id; $usage" >&2; exit 64; }
mkdir -p "$dir"
umask 077
if [ ! -f "$dir/ca.pem" ]; then
    openssl req -x509 -newkey rsa:2048 -nodes -days "$days" -subj "/CN=posed-ca" \
        -keyout "$dir/ca.key" -out "$dir/ca.pem" 2>/dev/null
fi
sign() {  # sign CN [BASE]: a key BASE.key and a certificate BASE.pem (default DIR/CN) signed by the CA
    out=${2:-$dir/$1}
    openssl req -newkey rsa:2048 -nodes -subj "/CN=$1" -keyout "$out.key" -out "$out.csr" 2>/dev/null
    printf 'basicConstraints=CA:FALSE\nextendedKeyUsage=serverAuth,clientAuth\nsubjectAltName=%s\n' "$san" \
        > "$out.ext"
    openssl x509 -req -in "$out.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" -CAcreateserial -days "$days" \
        -extfile "$out.ext" -out "$out.pem" 2>/dev/null
    rm -f "$out.csr" "$out.ext"
    chmod 644 "$out.pem"
    echo "$out.pem"
}
if [ -z "$robots" ]; then
    [ -f "$dir/posed-daemon.pem" ] || sign posed-daemon
fi
for id in $robots; do
    mkdir -p "$dir/robots/$id"
    sign "posed-daemon.$id" "$dir/robots/$id/posed-daemon"
    cp "$dir/ca.pem" "$dir/robots/$id/ca.pem"
    chmod 644 "$dir/robots/$id/ca.pem"
done
next_is_robot=""
for arg in "$@"; do
    if [ -n "$next_is_robot" ]; then next_is_robot=""
    elif [ "$arg" = "--robot" ]; then next_is_robot=1
    else sign "$arg"
    fi
done
chmod 644 "$dir"/*.pem
