"""Without the compiled module, knotmm.plugin still imports and says why it is unusable.

These tests run whether or not the plugin is built (conftest skips the others).
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

NEEDS_PLUGIN = False


def test_missing_module_is_reported_not_raised():
    code = textwrap.dedent("""
        import sys
        sys.modules["knotmm.plugin.rpyplugin"] = None  # as if it was never built
        import knotmm.plugin as kp
        assert kp.available() is False
        assert "could not be loaded" in kp.load_error()
        try:
            kp.RPYIntegrator(0.01)
        except kp.PluginUnavailableError as exc:
            assert isinstance(exc, ImportError)
            print("ok")
        """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
