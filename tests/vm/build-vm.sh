#!/usr/bin/env bash
# Builds the SocketCAN test VM from Debian packages (idempotent, cached).
#
#   tests/vm/build-vm.sh [--share-host] OUTDIR [EXECUTABLE | SRC=DEST ...]
#
# Produces OUTDIR/kernel (link into the cache) and OUTDIR/initrd.cpio.gz: a Debian bookworm
# kernel (downloaded with apt-get download, unpacked with dpkg-deb -x, never
# installed), busybox-static, the CAN modules (can-dev, vcan, can, can-raw),
# tests/vm/init.sh as /init, the given executables in /bin, and data files
# given as SRC=DEST (absolute DEST inside the image).  Dynamic executables get
# their loader and shared libraries copied too (static ones need none).
# --share-host adds the virtio and 9p modules, so /init can mount the host's
# root and an output folder that run-vm.sh --share-host exports.
# /etc/hdvm-modules lists the modules in load order for /init.
#
# Downloads are cached in $HD_VM_CACHE (default: <repo>/build/vm/cache), so
# only the first run needs the network (deb.debian.org).
set -euo pipefail

die() { echo "build-vm: ERROR: $*" >&2; exit 1; }
share=0
if [ "${1:-}" = --share-host ]; then share=1; shift; fi
[ $# -ge 1 ] || die "usage: $0 [--share-host] OUTDIR [EXECUTABLE...]"
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
out=$1; shift
cache=${HD_VM_CACHE:-$root/build/vm/cache}
mkdir -p "$out" "$cache"

for tool in apt-get apt-cache dpkg-deb cpio gzip flock; do
  command -v "$tool" >/dev/null || die "missing host tool '$tool'"
done

# Several builds may share the cache: serialise the download/unpack step.
exec 9>"$cache/.lock"
flock 9

# Resolve the flavour once and keep it, so later runs need no apt metadata.
if [ ! -s "$cache/kernel-package" ]; then
  pkg=${HD_VM_KERNEL_PKG:-$(apt-cache depends linux-image-amd64 2>/dev/null \
        | sed -n 's/^ *Depends: \(linux-image-[0-9].*-amd64\)$/\1/p' | head -n1)}
  [ -n "$pkg" ] || die "cannot resolve the Debian kernel package (apt-cache depends linux-image-amd64 gave nothing; run apt-get update?)"
  echo "$pkg" >"$cache/kernel-package"
fi
kpkg=$(cat "$cache/kernel-package")

fetch() { # package -> cached .deb path
  local p=$1 deb
  deb=$(ls "$cache"/debs/"${p}"_*.deb 2>/dev/null | head -n1 || true)
  if [ -z "$deb" ]; then
    mkdir -p "$cache/debs"
    echo "build-vm: downloading $p (first run only)" >&2
    (cd "$cache/debs" && apt-get download "$p" >&2) || die "apt-get download $p failed (no network?)"
    deb=$(ls "$cache"/debs/"${p}"_*.deb | head -n1)
  fi
  echo "$deb"
}

unpack() { # package dir
  local p=$1 dir=$2 deb
  if [ ! -e "$dir/.done" ]; then
    deb=$(fetch "$p")
    rm -rf "$dir"; mkdir -p "$dir"
    dpkg-deb -x "$deb" "$dir" || die "dpkg-deb -x $deb failed"
    touch "$dir/.done"
  fi
}

unpack "$kpkg" "$cache/kernel"
unpack busybox-static "$cache/busybox"

vmlinuz=$(ls "$cache"/kernel/boot/vmlinuz-* | head -n1)
[ -f "$vmlinuz" ] || die "no vmlinuz in $kpkg"

# The uncompressed ELF kernel boots through its PVH entry (QEMU -kernel
# vmlinux): no real-mode setup, no decompression under TCG -- about 6 s less
# per boot on this host.  Extracted once into the cache; if that fails the
# compressed bzImage is used (slower, same result).
if [ ! -s "$cache/vmlinux" ] && [ ! -e "$cache/vmlinux.none" ]; then
  if python3 - "$vmlinuz" "$cache/vmlinux.tmp" <<'PY' && readelf -n "$cache/vmlinux.tmp" 2>/dev/null | grep -q 0x00000012
import lzma, sys, zlib
data = open(sys.argv[1], "rb").read()
for magic, dec in ((b"\xfd7zXZ\x00", lambda b: lzma.LZMADecompressor().decompress(b)),
                   (b"\x1f\x8b\x08\x00", lambda b: zlib.decompressobj(31).decompress(b))):
    at = data.find(magic)
    while at >= 0:
        try:
            out = dec(data[at:])
        except Exception:
            out = b""
        if out[:4] == b"\x7fELF":
            open(sys.argv[2], "wb").write(out)
            sys.exit(0)
        at = data.find(magic, at + 1)
sys.exit(1)
PY
  then
    mv "$cache/vmlinux.tmp" "$cache/vmlinux"
  else
    rm -f "$cache/vmlinux.tmp"; touch "$cache/vmlinux.none"
    echo "build-vm: note: no PVH vmlinux in $vmlinuz; booting the bzImage (slower)" >&2
  fi
fi
flock -u 9
kver=${vmlinuz##*/vmlinuz-}
moddir=$cache/kernel/lib/modules/$kver/kernel
busybox=$cache/busybox/bin/busybox
[ -x "$busybox" ] || die "no busybox in busybox-static"

stage=$(mktemp -d "$out/stage.XXXXXX")
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage"/{bin,lib/modules,proc,sys,dev,tmp,etc}
cp "$busybox" "$stage/bin/busybox"
ln -s busybox "$stage/bin/sh"

# Load order matters: can-dev, vcan (needs can-dev on 6.1), can, can-raw;
# then (--share-host) each module after those it depends on (their
# modinfo "depends=": the package ships no modules.dep).
modules="drivers/net/can/dev/can-dev drivers/net/can/vcan net/can/can net/can/can-raw"
if [ $share = 1 ]; then
  modules="$modules drivers/virtio/virtio_ring drivers/virtio/virtio
    drivers/virtio/virtio_pci_legacy_dev drivers/virtio/virtio_pci_modern_dev
    drivers/virtio/virtio_pci fs/netfs/netfs fs/fscache/fscache net/9p/9pnet
    net/9p/9pnet_virtio fs/9p/9p"
fi
for m in $modules; do
  name=${m##*/}
  echo "$name" >>"$stage/etc/hdvm-modules"
  if [ -f "$moddir/$m.ko" ]; then
    cp "$moddir/$m.ko" "$stage/lib/modules/$name.ko"
  elif [ -f "$moddir/$m.ko.xz" ]; then
    xz -dc "$moddir/$m.ko.xz" >"$stage/lib/modules/$name.ko"
  else
    die "module $m.ko not in $kpkg (this flavour has no CAN or 9p support?)"
  fi
done

cp "$here/init.sh" "$stage/init"
chmod 755 "$stage/init"

for item in "$@"; do
  case $item in
    *=*)
      src=${item%%=*} dest=${item#*=}
      [ -f "$src" ] || die "data file '$src' not found"
      mkdir -p "$stage$(dirname "$dest")"
      cp "$src" "$stage$dest"
      continue ;;
  esac
  exe=$item
  [ -x "$exe" ] || die "executable '$exe' not found (build the vm test targets first)"
  cp "$exe" "$stage/bin/"
  # Dynamic executables: copy the loader and libraries to the same paths.
  if ldd "$exe" >/dev/null 2>&1; then
    for lib in $(ldd "$exe" | grep -o '/[^ ]*'); do
      mkdir -p "$stage$(dirname "$lib")"
      cp -L "$lib" "$stage$lib"
    done
  fi
done

(cd "$stage" && find . -mindepth 1 | LC_ALL=C sort | cpio -o -H newc --quiet) \
  | gzip -1 >"$out/initrd.cpio.gz.tmp"
mv "$out/initrd.cpio.gz.tmp" "$out/initrd.cpio.gz"
if [ -s "$cache/vmlinux" ]; then
  ln -sf "$cache/vmlinux" "$out/kernel"
else
  ln -sf "$vmlinuz" "$out/kernel"
fi
echo "build-vm: $out/kernel ($kpkg) + $out/initrd.cpio.gz ($(du -k "$out/initrd.cpio.gz" | cut -f1) KiB)"
