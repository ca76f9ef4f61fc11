MODULE tcpcal_tools
  ! tcpcal tool table of robot cell7 KR16: 2 tool(s)
  ! tool torch (tool 3) version 4
  ! calibrated 2026-11-24 05:00 UTC by alice (xyz_npoint)
  ! https://tcpcal.plant.example/ui/tools/t3
  ! tool gripper Duse (tool 1) version 4
  ! calibrated 2026-11-24 05:00 UTC by alice (xyz_npoint)
  ! https://tcpcal.plant.example/ui/tools/t1
  ! from https://tcpcal.plant.example
  ! left out: xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx: an ABB tooldata needs
  ! the tool's mass (kg, > 0); tool
  ! 'xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx' has none.
  ! ABB controllers refuse a held tool with mass 0: set the tool's load
  ! (mass_kg, cog_mm) first
  ! changes only the tooldata torch (declared here), tGripper
  ! (T_ROB1/user/tGripper); every other tool and all other data of the
  ! controller are untouched
  ! load it into task T_ROB1 (Program Editor, Modules, Load Module), then run
  ! tcpcal_set_tools once (PP to Routine): it assigns the values. Loading
  ! alone may leave a tooldata already in use as it was
  PERS tooldata torch:=[TRUE,[[1.5,-2.25,150.0],[0.707106781,0.0,-0.707106781,0.0]],[2.5,[0.0,0.0,80.0],[1,0,0,0],0,0,0]];
  PROC tcpcal_set_tools()
    torch:=[TRUE,[[1.5,-2.25,150.0],[0.707106781,0.0,-0.707106781,0.0]],[2.5,[0.0,0.0,80.0],[1,0,0,0],0,0,0]];
    tGripper:=[TRUE,[[0.0,12.0,95.5],[1.0,0.0,0.0,0.0]],[4.25,[5.0,0.0,40.0],[1,0,0,0],0,0,0]];
  ENDPROC
ENDMODULE
