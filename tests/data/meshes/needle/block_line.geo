// A 50 mm block with a vertical line of nodes on x = z = 25 mm from its top (y = 50 mm) down to
// y = 15 mm, for the needle's lateral-drag test against a rigid line inclusion in the same mesh
// (tests/engine/test_needle.cpp). Made at build time (tests/CMakeLists.txt, into
// build/tests/data/needle) with gmsh 4 (Debian):
//   gmsh -3 block_line.geo -o block_line_h5.msh
SetFactory("OpenCASCADE");
DefineConstant[ lc = 5e-3 ];
Box(1) = {0, 0, 0, 0.05, 0.05, 0.05};
Point(100) = {0.025, 0.015, 0.025, lc};
Point(101) = {0.025, 0.05, 0.025, lc};
Line(100) = {100, 101};
BooleanFragments{ Volume{1}; Delete; }{ Line{100}; Delete; }
Mesh.CharacteristicLengthMin = lc;
Mesh.CharacteristicLengthMax = lc;
Mesh.MshFileVersion = 2.2;
Mesh.Optimize = 1;
Physical Volume("block") = {1};
