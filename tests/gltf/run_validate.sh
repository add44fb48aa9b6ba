#!/usr/bin/env bash
# ctest: makes a small animation with the kinemesh CLI (character, take, LBS playback) and
# checks the .glb with the Khronos glTF validator (npm gltf-validator, installed by
# scripts/deps.sh). Fails when node or the validator is missing: it is part of the set-up.
set -euo pipefail
BIN=$1
WORK=$2
HERE=$(cd "$(dirname "$0")" && pwd)
command -v node >/dev/null || { echo "FAIL: node not found (scripts/deps.sh installs it)"; exit 1; }
[ -d "$HERE/node_modules/gltf-validator" ] || { echo "FAIL: $HERE/node_modules/gltf-validator missing (run scripts/deps.sh)"; exit 1; }
rm -rf "$WORK" && mkdir -p "$WORK"
"$BIN" gen character --vertices 2000 -o "$WORK/c.obj"
"$BIN" gen motion --kind wave --frames 12 --character "$WORK/c.obj" -o "$WORK/t.json"
"$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" -o "$WORK/every.glb"
"$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" --key-every 4 -o "$WORK/keys.glb"
# A textured copy (vt per vertex from x and y, faces v/t): TEXCOORD_0, NORMAL and NORMAL morph
# targets must validate too.
awk 'NR==FNR { if ($1 == "v") printf "vt %.6f %.6f\n", ($2 + 1) / 2, $3 / 2; next }
     $1 == "f" { printf "f %d/%d %d/%d %d/%d\n", $2, $2, $3, $3, $4, $4; next } { print }' \
  "$WORK/c.obj" "$WORK/c.obj" > "$WORK/ct.obj"
# with a material: a 1x1 PNG as its base colour texture (mtllib / usemtl / map_Kd), which every
# .glb made from it carries (images, textures, materials validated with the rest)
base64 -d >"$WORK/ct.png" <<<"iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8BQDwAEhQGAhKmMIQAAAABJRU5ErkJggg=="
# with a normal map (map_Bump, -bm its scale) and an emissive map of the same image (one image
# in the file, two textures naming it) and an emissive colour (Ke)
base64 -d >"$WORK/ctn.png" <<<"iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR4nGNoaPj/HwAGggL/s75RMwAAAABJRU5ErkJggg=="
# and a second, plain material on the second half of its faces (two primitives in the .glb)
printf 'newmtl skin\nKd 0.8 0.8 0.8\nmap_Kd ct.png\nmap_Bump -bm 0.5 ctn.png\nKe 0.1 0.2 0.3\nmap_Ke ctn.png\nnewmtl plain\nKd 0.2 0.4 0.6\n' >"$WORK/ct.mtl"
awk 'BEGIN { print "mtllib ct.mtl"; print "usemtl skin" }
     NR == FNR { if ($1 == "f") nf++; next }
     $1 == "f" && ++k == int(nf / 2) + 1 { print "usemtl plain" } { print }' \
  "$WORK/ct.obj" "$WORK/ct.obj" >"$WORK/ct2.obj" && mv "$WORK/ct2.obj" "$WORK/ct.obj"
cp "$WORK/c.rig.json" "$WORK/ct.rig.json"
# A scan's vertex colours (v x y z r g b): COLOR_0 on every .glb made from it, plain and
# compressed, a linear normalised unsigned short VEC4
awk '$1 == "v" { printf "%s %s %s %s %.4f %.4f 0.5\n", $1, $2, $3, $4, ($2 + 1) / 2, $3 / 2; next } { print }' \
  "$WORK/c.obj" >"$WORK/cc.obj"
cp "$WORK/c.rig.json" "$WORK/cc.rig.json"
"$BIN" pose --mesh "$WORK/cc.obj" --motion "$WORK/t.json" --key-every 4 -o "$WORK/colors.glb"
"$BIN" animate --mesh "$WORK/cc.obj" --motion "$WORK/t.json" --export skin:8 --compress -o "$WORK/z_colors.glb"
for f in colors z_colors; do
  node -e '
const b = require("fs").readFileSync(process.argv[1]);
const j = JSON.parse(b.subarray(20, 20 + b.readUInt32LE(12)).toString());
const a = j.accessors[j.meshes[0].primitives[0].attributes.COLOR_0];
if (!a || a.type !== "VEC4" || a.componentType !== 5123 || !a.normalized) {
  console.log("FAIL: " + process.argv[1] + ": no COLOR_0 (VEC4 normalised unsigned short)"); process.exit(1);
}' "$WORK/$f.glb"
done
"$BIN" pose --mesh "$WORK/ct.obj" --motion "$WORK/t.json" --key-every 4 -o "$WORK/textured.glb"
# Issue 11: the textured mesh through the puppetry pipeline (animate) too, its cache kept here.
XDG_CACHE_HOME="$WORK/cache" "$BIN" animate --mesh "$WORK/ct.obj" --motion "$WORK/t.json" -o "$WORK/textured_anim.glb"
# Issue 16: a skinned export (SSDR fit; JOINTS_0/WEIGHTS_0, inverse bind matrices, TRS channels).
"$BIN" pose --mesh "$WORK/ct.obj" --motion "$WORK/t.json" --export skin -o "$WORK/skin.glb"  # seeded by the rig
# pose --export skeleton: the rig's own skeleton (named joints) and weights, exact, no fit;
# plain and compressed
"$BIN" pose --mesh "$WORK/ct.obj" --motion "$WORK/t.json" --export skeleton -o "$WORK/skel.glb"
"$BIN" pose --mesh "$WORK/ct.obj" --motion "$WORK/t.json" --export skeleton --compress -o "$WORK/z_skel.glb"
# its joints keep the rig's hierarchy: ElbowLeft's node is a child of ShoulderLeft's
node -e '
const b = require("fs").readFileSync(process.argv[1]);
const j = JSON.parse(b.subarray(20, 20 + b.readUInt32LE(12)).toString());
const idx = (n) => j.nodes.findIndex((x) => x.name === n);
const s = idx("ShoulderLeft"), e = idx("ElbowLeft");
if (s < 0 || e < 0 || !(j.nodes[s].children || []).includes(e) || j.skins[0].joints.length !== 20) {
  console.log("FAIL: skel.glb: ElbowLeft is not a child of ShoulderLeft"); process.exit(1);
}' "$WORK/skel.glb"
# a ground quad under the character's feet: rig leaves it out of the skin, and the skeleton
# export binds it to the armature's root, one more joint (21), which no channel moves
awk -f "$HERE/../data/ground_quad.awk" "$WORK/c.obj" > "$WORK/cg.obj"
"$BIN" rig "$WORK/cg.obj" -o "$WORK/cg.rig.json" >/dev/null
"$BIN" pose --mesh "$WORK/cg.obj" --motion "$WORK/t.json" --export skeleton -o "$WORK/ground_skel.glb"
"$BIN" pose --mesh "$WORK/cg.obj" --motion "$WORK/t.json" --export skeleton --compress -o "$WORK/z_ground_skel.glb"
node -e '
const b = require("fs").readFileSync(process.argv[1]);
const j = JSON.parse(b.subarray(20, 20 + b.readUInt32LE(12)).toString());
const js = j.skins[0].joints;
if (js.length !== 21 || js[20] !== 1 || j.nodes[1].name !== "armature" ||
    j.animations[0].channels.some((c) => c.target.node === 1)) {
  console.log("FAIL: ground_skel.glb: the ground is not bound to the armature root, joint 21"); process.exit(1);
}' "$WORK/ground_skel.glb"
if "$BIN" animate --mesh "$WORK/c.obj" --motion "$WORK/t.json" --export skeleton -o "$WORK/x.glb" 2>/dev/null; then
  echo "FAIL: animate accepted --export skeleton (its frames are not skinned by a skeleton)"; exit 1
fi
# kinemesh bake: the per-frame morph file back to a skin, and a pc2 + rest mesh to a skin.
"$BIN" bake "$WORK/every.glb" --export skin:8 -o "$WORK/baked.glb"
"$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" -o "$WORK/every.pc2"
"$BIN" bake "$WORK/every.pc2" --mesh "$WORK/ct.obj" --max-error-mm 20 -o "$WORK/baked_pc2.glb"
"$BIN" pose --mesh "$WORK/ct.obj" --motion "$WORK/t.json" --export morphs:5 -o "$WORK/pca.glb"
# --compress (KHR_mesh_quantization + EXT_meshopt_compression) on every kind; the validator
# does not decode meshopt views (it reports the extension as an info), it checks the rest.
"$BIN" pose --mesh "$WORK/ct.obj" --motion "$WORK/t.json" --key-every 4 --compress -o "$WORK/z_keys.glb"
"$BIN" pose --mesh "$WORK/ct.obj" --motion "$WORK/t.json" --export skin --compress -o "$WORK/z_skin.glb"
"$BIN" pose --mesh "$WORK/ct.obj" --motion "$WORK/t.json" --export morphs:5 --compress -o "$WORK/z_pca.glb"
"$BIN" bake "$WORK/every.pc2" --mesh "$WORK/c.obj" --export skin:8 --compress -o "$WORK/z_baked.glb"
if "$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" --compress -o "$WORK/z.pc2" 2>/dev/null; then
  echo "FAIL: --compress accepted a .pc2 output"; exit 1
fi
for f in every keys textured textured_anim skin skel z_skel ground_skel z_ground_skel baked baked_pc2 pca z_keys z_skin z_pca z_baked colors z_colors; do
  # the textured mesh's outputs have a normal map and no TANGENT, as intended (validate.mjs)
  allow=()
  case $f in every | keys | baked | z_baked | colors | z_colors) ;; *) allow=(--allow MESH_PRIMITIVE_GENERATED_TANGENT_SPACE) ;; esac
  node "$HERE/validate.mjs" "${allow[@]}" "$WORK/$f.glb" | tee "$WORK/$f.txt"
  grep -q ': 0 errors, 0 warnings' "$WORK/$f.txt" || { echo "FAIL: $f.glb has validator errors or warnings"; exit 1; }
done
# info lists the two materials as read (the runs of faces, the texture on the first)
"$BIN" info --json "$WORK/ct.obj" | node -e '
const m = JSON.parse(require("fs").readFileSync(0)).materials;
if (m.length !== 2 || m[0].texture !== "image/png" || m[1].texture !== undefined ||
    m[1].first_face !== m[0].faces) { console.log("FAIL: info --json materials", JSON.stringify(m)); process.exit(1); }'
# the textured mesh's outputs carry its two materials (and the image) on two primitives
nf=$(grep -c '^f ' "$WORK/ct.obj")
export nf
for f in textured textured_anim skin skel z_skel pca z_keys z_skin z_pca; do
  node -e '
const nf = Number(process.env.nf);
const b = require("fs").readFileSync(process.argv[1]);
const j = JSON.parse(b.subarray(20, 20 + b.readUInt32LE(12)).toString());
const m = j.materials || [], p = j.meshes[0].primitives;
const nt = m[0] && m[0].normalTexture, et = m[0] && m[0].emissiveTexture;
if (m.length !== 2 || p.length !== 2 || p[0].material !== 0 || p[1].material !== 1 ||
    !m[0].pbrMetallicRoughness.baseColorTexture || m[1].pbrMetallicRoughness.baseColorTexture ||
    !nt || nt.scale !== 0.5 || !et || j.textures[nt.index].source !== j.textures[et.index].source ||
    String(m[0].emissiveFactor) !== "0.1,0.2,0.3" || m[1].normalTexture ||
    (j.images || []).length !== 2 || p[0].indices === p[1].indices ||
    j.accessors[p[0].indices].count + j.accessors[p[1].indices].count !== 3 * nf) {
  console.log("FAIL: " + process.argv[1] + ": expected the two materials on two primitives, the textured one first, with its normal and emissive maps"); process.exit(1);
}' "$WORK/$f.glb"
done
"$BIN" info --json "$WORK/every.glb" | grep -Eq '"frames":[[:space:]]*12,' || { echo "FAIL: info does not report 12 frames"; exit 1; }
"$BIN" info --json "$WORK/skin.glb" | grep -Eq '"frames":[[:space:]]*12,' || { echo "FAIL: info does not report 12 frames for the skin"; exit 1; }
echo "gltf_validator: 18 passed, 0 failed"
