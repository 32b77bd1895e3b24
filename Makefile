# Shortcuts; each target is one documented command (see README.md and the docs/ site).
.PHONY: install quick test test-all reproduce reproduce-ch4 report-ch4 reproduce-ch5 reproduce-ch5-perception reproduce-ch5-hrc reproduce-ch6 reproduce-ch6-robot reproduce-data mlflow-ui docs

install:
	bash scripts/install.sh

quick: install  ## Table 4.1's 3of5 and 4of5 cells for fold 0 (2.5 min after the install), printed at the end
	.venv/bin/hrc-lab experiment=ch4/table_4_1_quick hydra/launcher=joblib

test: install
	.venv/bin/python -m pytest

test-all: install  ## including slow end-to-end tests
	.venv/bin/python -m pytest -m ""

# ARGS=--check also compares the fresh reports' tables with the committed ones; ARGS=--dry-run prints the plan
reproduce: install  ## every chapter's sweeps, then every report, with each step's wall time (hrc-lab-reproduce -h)
	.venv/bin/hrc-lab-reproduce all $(ARGS)

reproduce-ch4: install  ## every Ch.4 reasoning table and figure, then the committed report
	.venv/bin/hrc-lab-reproduce ch4_reasoning $(ARGS)

report-ch4:
	.venv/bin/hrc-lab-report ch4_reasoning

reproduce-ch5: install  ## Fig. 5.7 and the planner columns of Table 5.2, then the committed report
	.venv/bin/hrc-lab-reproduce ch5_planner $(ARGS)

reproduce-ch5-perception: install  ## Fig. 5.5/5.6 and Table 5.2 end to end from generated videos, then the report
	.venv/bin/hrc-lab-reproduce ch5_perception $(ARGS)

reproduce-ch5-hrc: install  ## the HRC loop with the robot cell (Table 5.2 extended, side-by-side video), then the report
	.venv/bin/hrc-lab-reproduce ch5_hrc $(ARGS)

reproduce-ch6: install  ## Tables 6.1, 6.2 (both rows) and 6.3, then both Ch.6 reports
	.venv/bin/hrc-lab-reproduce ch6 $(ARGS)

reproduce-ch6-robot: install  ## Table 6.2's robot row (Algorithm 4 in the robosuite clutter cell), then its report
	.venv/bin/hrc-lab-reproduce ch6_robot $(ARGS)

reproduce-data: install  ## every demonstration set (runs/data/*.hdf5), the videos, then the committed report
	.venv/bin/hrc-lab-reproduce data $(ARGS)

mlflow-ui:  ## http://127.0.0.1:5000
	.venv/bin/mlflow ui --backend-store-uri sqlite:///runs/mlflow.db --host 127.0.0.1 --port 5000 --workers 1

docs: install  ## the documentation site into site/ (mkdocs.yml; CI builds it --strict; browse: .venv/bin/mkdocs serve)
	.venv/bin/mkdocs build --strict
