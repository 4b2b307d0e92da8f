#!/usr/bin/env bash
# Debian packages Appeal Lab needs at run time: a virtual screen for PsychoPy (xvfb),
# OSMesa for offscreen pyrender, the libraries pyglet/PsychoPy/psychtoolbox load, fonts, and the
# headless browser (chromium + chromium-driver) that runs exported online studies in the tests.
# As root, missing ones are installed with apt-get; otherwise the apt command is printed.
# Extra packages can be asked for as arguments (e.g. the R packages for benchmarks).
set -euo pipefail
PKGS=(xvfb xauth libosmesa6 libgl1 libglu1-mesa libegl1 libjack-jackd2-0 libasound2 libportaudio2
      libusb-1.0-0 libxkbcommon-x11-0 libxcursor1 libxinerama1 libxrandr2 libxxf86vm1 libxi6
      libglib2.0-0 libdbus-1-3 libnss3 fontconfig fonts-dejavu-core
      libxcb-icccm4 libxcb-keysyms1 libxcb-image0 libxcb-render-util0 libxcb-xkb1 libxcb-shape0
      libxcb-cursor0 libxcb-xinerama0 libxcb-randr0 libxkbcommon0 xdotool chromium chromium-driver "$@")
# npm installs jsPsych for `appeal export web`; Debian's nodejs + npm only where no npm is there
# (a NodeSource nodejs brings its own npm and conflicts with Debian's npm package)
command -v npm >/dev/null 2>&1 || PKGS+=(nodejs npm)
if ! command -v dpkg-query >/dev/null 2>&1; then
  echo "system-deps: not a Debian system; install the equivalents of: ${PKGS[*]}" >&2
  exit 0
fi
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
cmd="apt-get install -y --no-install-recommends ${missing[*]}"
if [ "$(id -u)" -eq 0 ]; then
  echo "system-deps: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  $cmd -qq
else
  echo "system-deps: missing Debian packages; run as root:  apt-get update && $cmd" >&2
fi
