# An OBJ with a ground quad added under it (4 vertices, 2 faces, 2 m square, 2 mm below its
# lowest vertex, y up), as a character comes out of a scene with its floor: the tests of rig's
# skin leaving a piece lying on the floor still (run_validate.sh, run_three.sh,
# run_blender.sh, test_recon_cli). Usage: awk -f ground_quad.awk in.obj > out.obj
$1 == "v" { n++; if (min == "" || $3 < min) min = $3 }
{ print }
END {
  y = min - 0.002
  printf "v -1 %g -1\nv 1 %g -1\nv 1 %g 1\nv -1 %g 1\n", y, y, y, y
  printf "f %d %d %d\nf %d %d %d\n", n + 1, n + 3, n + 2, n + 1, n + 4, n + 3
}
