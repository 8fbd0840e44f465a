// A clamped circular plate for the bending test at nu 0.49 (tests/engine/test_locking_free.cpp):
// radius 30 mm, thickness 3 mm. Made with gmsh 4 (Debian):
//   gmsh -3 disc.geo -setnumber lc 2.5e-3 -o disc_a30_t3_lc2p5.msh
//   gmsh -3 disc.geo -setnumber lc 1.7e-3 -o disc_a30_t3_lc1p7.msh
// and at build time (tests/CMakeLists.txt, into build/tests/data/plate):
//   gmsh -3 disc.geo -setnumber lc 1.0e-3 -o disc_a30_t3_lc1p0.msh
SetFactory("OpenCASCADE");
DefineConstant[ lc = 2.5e-3 ];
Cylinder(1) = {0, 0, 0, 0, 0, 0.003, 0.03, 2*Pi};
Mesh.CharacteristicLengthMin = lc;
Mesh.CharacteristicLengthMax = lc;
Mesh.MshFileVersion = 2.2;
Mesh.Optimize = 1;
Physical Volume("plate") = {1};
