MODULE tcpcal_torch
  ! tcpcal tool data
  ! tool torch (tool 3) version 4
  ! calibrated 2026-11-24 05:00 UTC by alice (xyz_npoint)
  ! https://tcpcal.plant.example/ui/tools/t3
  ! from https://tcpcal.plant.example
  ! changes only the tooldata torch (declared here); every other tool and all
  ! other data of the controller are untouched
  ! load it into the robot's motion task (e.g. T_ROB1) (Program Editor,
  ! Modules, Load Module), then run tcpcal_set_torch once (PP to Routine): it
  ! assigns the values. Loading alone may leave a tooldata already in use as
  ! it was
  PERS tooldata torch:=[TRUE,[[1.5,-2.25,150.0],[0.707106781,0.0,-0.707106781,0.0]],[2.5,[0.0,0.0,80.0],[1,0,0,0],0,0,0]];
  PROC tcpcal_set_torch()
    torch:=[TRUE,[[1.5,-2.25,150.0],[0.707106781,0.0,-0.707106781,0.0]],[2.5,[0.0,0.0,80.0],[1,0,0,0],0,0,0]];
  ENDPROC
ENDMODULE
