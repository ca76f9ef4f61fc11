"""The `tcpcal` command's tests (app/cli/), its requests sent to the app in process."""
