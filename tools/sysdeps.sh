#!/usr/bin/env bash
# What `make demo` and `make test` need from the system, checked before the
# build (the Makefile's sysdeps targets call this):
#   tools/sysdeps.sh demo  the build (python3 with venv, g++, libglib-2.0) and
#                          an LCM multicast route on this host (the demo's
#                          processes talk over udpm with ttl=0)
#   tools/sysdeps.sh test  the build, plus what the tests run: Xvfb, a JDK
#                          (javac, jar) with the JRE's X11 AWT for lcm-spy's
#                          window, a headless Chromium, iproute2 (ip, tc),
#                          nftables and iptables (a lossy link where tc has
#                          no netem: loss/dup/corruption by nft rules, delay
#                          and reordering through an NFQUEUE delay line); a
#                          multicast route only when the tests cannot make
#                          their own network namespace (tests/lcmnet.py)
# When something is missing: as root with apt-get, install it (Debian
# packages) and say so; otherwise stop at once with the command to run.
# Silent, and no apt-get update, when everything is there.
set -euo pipefail

mode=${1:-}
case $mode in
  demo | test) ;;
  *) echo "usage: $0 demo|test" >&2; exit 2 ;;
esac
PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}
GROUP=239.255.76.67  # LCM's default group (sc_rt.wire.lcmio.DEFAULT_URL)

# sbin too: ip, tc and ldconfig live there, outside a Debian user's PATH.
sbin() { PATH="$PATH:/usr/local/sbin:/usr/sbin:/sbin" "$@"; }
have() { sbin command -v "$1" >/dev/null 2>&1; }
is_root() { [ "$(id -u)" = 0 ]; }

pkgs=()
need() { case " ${pkgs[*]} " in *" $1 "*) ;; *) pkgs+=("$1") ;; esac; }

check_packages() {
  pkgs=()
  # the build: .venv from $PYTHON (Debian splits venv/ensurepip off), g++, the lcm wheel's glib
  if [ ! -x "$VENV/bin/python" ]; then
    if ! have "$PYTHON"; then need python3; need python3-venv
    elif ! "$PYTHON" -c 'import ensurepip, venv' >/dev/null 2>&1; then need python3-venv
    fi
  fi
  have g++ || need g++
  # the extension compiles against Python.h: Debian splits it off (python3-dev)
  if have "$PYTHON"; then
    "$PYTHON" -c 'import os, sys, sysconfig; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' >/dev/null 2>&1 || need python3-dev
  else need python3-dev
  fi
  sbin ldconfig -p 2>/dev/null | grep 'libglib-2\.0\.so\.0 ' >/dev/null || need libglib2.0-0
  have ip || need iproute2
  [ "$mode" = test ] || return 0
  have Xvfb || need xvfb
  { have javac && have jar; } || need default-jdk-headless
  # lcm-spy opens a Swing window under Xvfb: the headless JRE lacks libawt_xawt.so
  local java_home=""
  have java && java_home=$(dirname "$(dirname "$(readlink -f "$(command -v java)")")")
  [ -n "$java_home" ] && [ -e "$java_home/lib/libawt_xawt.so" ] || need default-jre
  have chromium || have chromium-browser || need chromium
  have tc || need iproute2
  # tests/test_netem.py impairs a veth with nftables where the kernel has no netem
  have nft || need nftables; have iptables-legacy || need iptables  # and its NFQUEUE delay line (delay, reordering)
}

check_packages
if [ ${#pkgs[@]} -gt 0 ]; then
  if is_root && have apt-get; then
    echo "sc-rt: installing ${pkgs[*]} (apt-get) ..."
    export DEBIAN_FRONTEND=noninteractive
    lock=(-o DPkg::Lock::Timeout=600)  # wait for another apt-get rather than fail
    apt-get "${lock[@]}" update -q
    apt-get "${lock[@]}" install -y -q "${pkgs[@]}"
    check_packages
    if [ ${#pkgs[@]} -gt 0 ]; then
      echo "sc-rt: still missing after apt-get install: ${pkgs[*]}" >&2
      exit 1
    fi
  else
    echo "sc-rt: make $mode needs system packages that are missing: ${pkgs[*]}. Install them with:" >&2
    echo "  sudo apt-get install -y ${pkgs[*]}" >&2
    have apt-get || echo "(Debian/Ubuntu package names; install the equivalents on this system)" >&2
    exit 1
  fi
fi

if [ ! -x "$VENV/bin/python" ] && ! "$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
  echo "sc-rt: needs Python >= 3.11 and $PYTHON is $("$PYTHON" -V 2>&1): run make with PYTHON=python3.11 (or newer)" >&2
  exit 1
fi

# LCM's udpm transport needs a route for its multicast group. The tests make
# their own network namespace with one when they may (root); the demo runs on
# this host and needs the host to have one.
ns_ok() {
  sbin unshare -n sh -c "ip link set lo up && ip route add 224.0.0.0/4 dev lo" >/dev/null 2>&1
}
route_ok() { sbin ip route get "$GROUP" >/dev/null 2>&1; }

if [ "$mode" = test ] && ns_ok; then exit 0; fi
route_ok && exit 0
if is_root; then
  echo "sc-rt: adding a multicast route on lo for LCM (ip route add 224.0.0.0/4 dev lo; ttl=0 keeps packets on this machine) ..."
  if ! { ip link set lo up && ip route add 224.0.0.0/4 dev lo; }; then
    echo "sc-rt: could not add the route (no permission to change this machine's network?)" >&2
    exit 1
  fi
else
  echo "sc-rt: LCM needs a multicast route and this machine has none. Add one with:" >&2
  echo "  sudo ip route add 224.0.0.0/4 dev lo" >&2
  exit 1
fi
